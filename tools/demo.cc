// flysfm demo: the whole pipeline on a scene the program renders itself, fed
// to the engine as a live capture would be, then the poses compared with the
// rendering's exact ground truth. Needs no data.

#include <cstdio>
#include <iostream>
#include <map>

#include "io/evaluation/evaluation.h"
#include "io/run/output_lock.h"
#include "io/synthetic/synthetic_source.h"
#include "tools/commands.h"
#include "tools/engine_flags.h"

namespace flysfm {

void AddDemoCommand(CLI::App& app) {
  struct Flags {
    EngineFlags engine;
    SyntheticCaptureOptions capture;
    double interval = 0;
  };
  auto flags = std::make_shared<Flags>();
  flags->engine.out = "flysfm_demo";
  CLI::App* command = app.add_subcommand(
      "demo", "Render a textured scene along a hand-held camera path, register each view "
              "as it arrives, and report the pose error against the exact ground truth");
  AddEngineFlags(command, &flags->engine);
  command->add_option("--views", flags->capture.num_views, "Number of views rendered")
      ->check(CLI::Range(2, 1000))
      ->capture_default_str();
  command->add_option("--seed", flags->capture.seed, "Scene and path seed")
      ->capture_default_str();
  command->add_option("--interval", flags->interval,
                      "Hand views to the engine this many seconds apart, like a camera")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->callback([flags]() {
    const OutputLock lock(flags->engine.out);
    std::printf("rendering %d views of the synthetic scene...\n", flags->capture.num_views);
    const SyntheticCapture capture = MakeSyntheticCapture(flags->capture);
    EngineFlags engine_flags = flags->engine;
    if (engine_flags.camera.empty()) engine_flags.camera = capture.camera.ToString();
    Engine engine = engine_flags.MakeEngine();
    FrameListSource source(capture.frames, flags->interval);
    CommandRun run;
    if (flags->interval == 0) run.between_images = RunLoop::Options::BetweenImages::kNothing;
    RunFromFlags(&source, &engine, engine_flags, run);

    const Reconstruction& model = engine.reconstruction();
    const std::optional<PositionErrors> errors =
        CompareCentersByName(model, capture.CameraCentres());
    const double extent = flags->capture.path_length;
    const bool all_registered = model.NumRegisteredImages() == capture.frames.size();
    const bool accurate = errors && errors->rmse < 0.005 * extent;
    if (errors) {
      std::printf("demo: %zu/%zu views registered; camera centres after Sim3: RMSE %.2f mm "
                  "(%.3f %% of the %.1f m path), max %.2f mm\n",
                  model.NumRegisteredImages(), capture.frames.size(), errors->rmse * 1000,
                  100 * errors->rmse / extent, extent, errors->max * 1000);
    } else {
      std::printf("demo: %zu/%zu views registered; too few to compare with ground truth\n",
                  model.NumRegisteredImages(), capture.frames.size());
    }
    std::printf("demo %s: every view registered and centres within 0.5 %% of the path\n",
                all_registered && accurate ? "passed" : "FAILED");
    if (!(all_registered && accurate)) throw CLI::RuntimeError(1);
  });
}

}  // namespace flysfm
