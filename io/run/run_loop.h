#pragma once

// The one loop that feeds an image source to the engine: `flysfm batch`,
// `live` and `demo`, every benchmark and the engine's regression tests run
// it, so that what they measure is what the program does.
//
// Per image: the next one is decoded and its features extracted on the
// second core (PreparedFrameSource) while the engine works on this one;
// quarantined images and those a resumed model holds are skipped; the
// engine's results are printed, logged, published to the live view, and the
// checkpoint and outputs kept current. Between images the engine refines the
// model while none waits (RefineUntilNextFrame). At the end: what
// refinement left, Engine::Finish, the final checkpoint and outputs.
//
// Bad input and faults never end the run: an engine exception on one image
// is reported naming it, counted and the image quarantined; a failed output
// write is counted and retried by the next one; a failing source ends the
// images, not the run.

#include <chrono>
#include <cstdio>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/engine.h"
#include "io/run/checkpoint.h"
#include "io/run/prepared_source.h"
#include "io/run/run_writer.h"
#include "io/sources/image_source.h"
#include "quality/coverage.h"
#include "quality/quality_tracker.h"

namespace flysfm {

class ViewServer;

class RunLoop {
 public:
  struct Options {
    // What the engine does between two images while none waits.
    enum class BetweenImages {
      // Nothing: images are fed as fast as the engine goes, so that the
      // model does not depend on the machine's speed; refinement happens
      // at the end only (an unpaced batch).
      kNothing,
      // Refinement slices until the next image arrives (live capture, a
      // paced batch): the model a photographer sees is refined as far as
      // the shooting rhythm allows.
      kRefineUntilNextImage,
      // All refinement that is left, before the next image is taken: a
      // camera slow enough for refinement to run out of work, the same on
      // any machine (tests of the refined model).
      kRefineToEnd,
    };
    BetweenImages between_images = BetweenImages::kRefineUntilNextImage;
    // With kRefineUntilNextImage: the share of the engine's core refinement
    // may take; after a slice of t seconds it rests t (1/share - 1) s.
    double refinement_share = 1.0;

    // The output folder (RunWriter: log.jsonl, sparse/, points.ply,
    // trajectory.txt, summary.json; OUT/state, the checkpoint; the
    // quarantine, OUT/quarantine.tsv). Empty: no outputs at all, as the
    // benchmarks run it.
    std::string out;
    // The model files and summary are rewritten at most this often.
    double refresh_seconds = 2.0;
    // Continue the model checkpointed in OUT/state, if any (images it holds
    // are skipped by name); else a new model, and the checkpoint starts over.
    bool resume = false;
    // Quarantined images get another try.
    bool retry_quarantined = false;
    Checkpointer::Options checkpoint;
    // The quality measures kept with the outputs (points.ply's per-vertex
    // measures, summary.json's "quality", log.jsonl's ms.quality); only
    // with an output folder. Kept here, not in the engine: the engine's
    // result stays what it was, whatever is measured of it.
    QualityTracker::Options quality;
    // The coverage surface and the suggested viewpoints (summary.json's
    // "coverage", surface.ply, log.jsonl's ms.coverage, the live view), with
    // an output folder; recomputed when the model changed, at most every
    // refresh_seconds and every ten times its last cost (it takes at most a
    // tenth of the run), and at the end. Its rule of "well covered" is the
    // points' (quality.min_views, quality.min_angle_deg).
    bool coverage = true;
    Coverage::Options coverage_options;

    // One line per image result, the end's progress (a line updating in
    // place on a terminal, plain lines elsewhere: io/run/progress_line.h)
    // and the run's closing lines, on `output`.
    bool print = true;
    std::FILE* output = stdout;
    // Plain progress lines repeat a step at most this often.
    double progress_interval_s = 5.0;
    // Each line also gives the delay from the image's arrival
    // (Frame::arrival) to its result, and the run ends with the median.
    bool live = false;
    // Input folder entries the listing could not examine, for summary.json.
    int skipped_entries = 0;
    // The tags of the sources a MergedSource (io/sources/merged_source.h)
    // merges, in its inputs' order; empty for a single source. Each gets
    // its counts in summary.json, even with no image yet, and an image a
    // resumed model holds is told its source by its name's `<tag>/`.
    std::vector<std::string> sources;

    // Throws std::invalid_argument naming the bad option.
    void Check() const;
  };

  // What a caller (a benchmark, a test) may watch or replace. Each is
  // optional.
  struct Hooks {
    // In place of Engine::AddImage (a test puts a fault here).
    std::function<std::vector<ImageResult>(Engine*, PreparedFrame)> add_image;
    // Before the engine takes an image: the model as the image arrives.
    std::function<void(const Engine&, const PreparedFrame&)> on_arrival;
    // After the engine took an image: that call's results and its wall
    // time (the engine's own, without the decode and features that ran
    // ahead).
    std::function<void(const Engine&, const std::vector<ImageResult>&, double call_ms)>
        on_image;
    // Once the image's results are reported and its checkpoint written: the
    // state a crash at this moment leaves behind.
    std::function<void(const Engine&)> after_image;
    // In place of Engine::Finish (a test of the end's progress lines puts a
    // slow one here).
    std::function<std::vector<ImageResult>(
        Engine*, const std::function<void(const Engine::FinishProgress&)>&)>
        finish;
  };

  // Where a result came from.
  enum class Origin {
    kArrival,     // the engine call of a new image (its own, or one it let register)
    kRefinement,  // a waiting image that registered between images
    kEnd,         // registered by the end's refinement or Finish
  };
  struct Reported {
    ImageResult result;
    Origin origin = Origin::kArrival;
    // The result of the image the engine call was for (kArrival only; the
    // call's other results are waiting images it let register).
    bool arriving_image = false;
    // From the image's arrival to this result; nullopt without an arrival
    // time.
    std::optional<double> delay_ms;
  };

  struct Call {
    std::string name;
    double engine_ms = 0;
    double checkpoint_ms = 0;
  };
  struct Summary {
    std::vector<Reported> results;  // in the order they were reported
    // Per image the engine took: its name, the engine call's wall time and
    // the checkpoint's after it.
    std::vector<Call> calls;
    RunCounts counts;
    Checkpointer::Summary checkpoint;
    // From the start (before resuming) to the last written output.
    double wall_s = 0;
    // From the start to the end of the last image's engine call.
    double last_image_s = 0;
    // From the end of the last image's call to the last written output:
    // the end's refinement, Finish, the final checkpoint and outputs.
    double end_s = 0;
    double finish_s = 0;  // Engine::Finish alone
    // 1 when the final outputs could not be written or the source failed.
    int exit_code = 0;
  };

  // `view`, when given, is published to and must outlive the run.
  explicit RunLoop(Options options, ViewServer* view = nullptr);

  // Runs every frame of `source` through `engine`. With options.resume the
  // engine first continues the checkpointed model (one that cannot be read:
  // std::runtime_error, before any image).
  Summary Run(ImageSource* source, Engine* engine, const Hooks& hooks = {});

 private:
  Options options_;
  ViewServer* view_;
};

}  // namespace flysfm
