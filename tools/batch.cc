// `flysfm batch DIR --out OUT`: a folder of photos or a TUM sequence, fed to
// the engine one image at a time as if each arrived on its own.

#include <iostream>

#include "io/run/output_lock.h"
#include "tools/commands.h"
#include "tools/engine_flags.h"

namespace flysfm {

void AddBatchCommand(CLI::App& app) {
  struct Flags {
    std::string input;
    EngineFlags engine;
    int shuffle_seed = -1;
    double interval = 0;
    int max_images = 0;
    bool view_keep = false;
  };
  auto flags = std::make_shared<Flags>();
  CLI::App* command = app.add_subcommand(
      "batch", "Process a folder of photos or a TUM RGB-D sequence folder (rgb.txt), "
               "image by image, with the same per-image results as live capture");
  command->add_option("input", flags->input, "Image folder or TUM sequence folder")
      ->required();
  AddEngineFlags(command, &flags->engine);
  command->add_option("--shuffle", flags->shuffle_seed,
                      "Feed the images in a random order from this seed (any capture "
                      "order must work); -1 keeps the name / rgb.txt order")
      ->capture_default_str();
  command->add_option("--interval", flags->interval,
                      "Hand images to the engine this many seconds apart, like a camera")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_flag("--resume", flags->engine.resume,
                    "Continue the model checkpointed in --out: an interrupted run, or a "
                    "finished one to extend with new images (images it holds, by name, are "
                    "skipped); without it a new model starts");
  command->add_option("--max-images", flags->max_images,
                      "Use only the first N images of the input (0: all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_flag("--view-keep", flags->view_keep,
                    "With --view: keep serving the page after the run, until Ctrl-C");
  command->callback([flags]() {
    int exit_code = 0;
    try {
      const OutputLock lock(flags->engine.out);
      std::vector<std::string> skipped;
      std::vector<Frame> frames = ListBatchInput(flags->input, &skipped);
      for (const std::string& entry : skipped) {
        std::cerr << "flysfm batch: skipped " << entry << "\n";
      }
      if (flags->max_images > 0 && int(frames.size()) > flags->max_images) {
        frames.resize(flags->max_images);
      }
      if (flags->shuffle_seed >= 0) ShuffleFrames(&frames, std::uint32_t(flags->shuffle_seed));
      FrameListSource source(std::move(frames), flags->interval);
      Engine engine = flags->engine.MakeEngine();
      CommandRun run;
      run.skipped_entries = int(skipped.size());
      run.keep_view = flags->view_keep;
      if (flags->interval == 0) run.between_images = RunLoop::Options::BetweenImages::kNothing;
      exit_code = RunFromFlags(&source, &engine, flags->engine, run);
    } catch (const std::invalid_argument& e) {
      std::cerr << "flysfm batch: " << e.what() << "\n";
      exit_code = 2;
    } catch (const std::exception& e) {
      std::cerr << "flysfm batch: " << e.what() << "\n";
      exit_code = 1;
    }
    if (exit_code != 0) throw CLI::RuntimeError(exit_code);
  });
}

}  // namespace flysfm
