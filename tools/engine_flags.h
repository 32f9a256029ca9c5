#pragma once

// Options shared by the commands that run the engine (batch, demo, live):
// the camera, the retrieval model, the ablation switches and the output.

#include <functional>
#include <map>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "core/engine.h"
#include "io/run/run_writer.h"
#include "io/sources/image_source.h"
#include "tools/view_flags.h"

namespace flysfm {

struct EngineFlags {
  std::string camera;           // "MODEL p1,p2,..."; empty: unknown
  std::string retrieval_model;  // file from train-retrieval; empty: bootstrap
  // Per EngineAblations() flag, whether it was given.
  std::map<std::string, bool> ablations;
  bool no_global_ba = false;
  // Refinement between images (Engine::Refine): off, or the share of the
  // engine's core it may take while no image waits (1: all of it).
  bool no_refinement = false;
  double refinement_share = 1.0;
  std::string out;
  double refresh_seconds = 2.0;
  bool retry_quarantined = false;
  // Continue the model checkpointed in OUT/state, if any; else a new model
  // (and the checkpoint starts over).
  bool resume = false;
  // DecodeOptions::max_image_pixels, in megapixels.
  double max_megapixels = DecodeOptions().max_image_pixels / 1e6;
  // LsmImageStore::Options::window_budget_megabytes.
  int lsm_window_budget_mb = LsmImageStore::Options().window_budget_megabytes;
  ViewFlags view;  // --view [PORT], --view-lan

  // Throws std::invalid_argument with a one-line message for a bad camera or
  // an unreadable retrieval model.
  Engine MakeEngine() const;
};

void AddEngineFlags(CLI::App* command, EngineFlags* flags);

struct RunEngineOptions {
  // Each line also gives the delay from the image's arrival (Frame::arrival)
  // to its result, and the run ends with the median delay.
  bool live = false;
  // Input folder entries the listing could not examine, for summary.json.
  int skipped_entries = 0;
  // Engine::AddImage; a test puts a fault here.
  std::function<std::vector<ImageResult>(Engine*, PreparedFrame)> add_image;
  // With --view: after the run, keep serving the page until Ctrl-C.
  bool keep_view = false;
  // Refine the model while no image waits (unless --no-refinement); else
  // only at the end. A batch fed as fast as the engine goes refines at the
  // end only, so that its model does not depend on the machine's speed.
  bool refine_between_images = true;
};

// Runs every frame of `source` through the engine, printing one line per
// image result and keeping `out` current, its checkpoint (OUT/state)
// included; ends with Finish() and the final model. With flags.resume the
// engine first continues the checkpointed model, and frames it holds are
// skipped (a checkpoint that cannot be read: std::runtime_error). Images
// quarantined in OUT/quarantine.tsv are skipped; an exception
// on one image is reported naming it, counted, and the image quarantined;
// the run goes on. A failed output write is reported and counted; the next
// write retries. Returns the process exit code: 1 when the final outputs
// could not be written or the source failed.
int RunEngine(ImageSource* source, Engine* engine, const EngineFlags& flags,
              const RunEngineOptions& options = {});

}  // namespace flysfm
