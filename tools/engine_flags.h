#pragma once

// Options shared by the commands that run the engine (batch, demo, live):
// the camera, the retrieval model, the ablation switches, the output and the
// run loop's options.

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "core/engine.h"
#include "io/run/run_loop.h"
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
  double refinement_share = RunLoop::Options().refinement_share;
  std::string out;
  double refresh_seconds = RunLoop::Options().refresh_seconds;
  // RunLoop::Options::coverage off: no surface, no suggested viewpoints.
  bool no_coverage = false;
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

// What a command adds to its flags for the run loop (io/run/run_loop.h).
struct CommandRun {
  // A batch fed as fast as the engine goes refines at the end only
  // (kNothing), so that its model does not depend on the machine's speed.
  RunLoop::Options::BetweenImages between_images =
      RunLoop::Options::BetweenImages::kRefineUntilNextImage;
  // Each line gives the delay from the image's arrival to its result.
  bool live = false;
  // Input folder entries the listing could not examine, for summary.json.
  int skipped_entries = 0;
  // With --view: after the run, keep serving the page until Ctrl-C.
  bool keep_view = false;
  // The tags of several merged sources (RunLoop::Options::sources); empty
  // for one source.
  std::vector<std::string> sources;
  RunLoop::Hooks hooks;
};

// Runs `source` through `engine` in the run loop with the options the flags
// ask for, serving the view they ask for (started before the first image,
// so that a port in use fails the run at once). Returns the process exit
// code: 1 when the final outputs could not be written or the source failed.
// A checkpoint that cannot be resumed from: std::runtime_error.
int RunFromFlags(ImageSource* source, Engine* engine, const EngineFlags& flags,
                 const CommandRun& run = {});

}  // namespace flysfm
