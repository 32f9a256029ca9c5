// `flysfm batch DIR --out OUT`: a folder of photos or a TUM sequence, fed to
// the engine one image at a time as if each arrived on its own.
// `flysfm batch A B C --out OUT`: one folder per photographer, interleaved
// as the shots were taken (io/sources/merged_source.h, docs/io.md).

#include <algorithm>
#include <iostream>
#include <memory>
#include <optional>
#include <vector>

#include "io/run/output_lock.h"
#include "io/sources/merged_source.h"
#include "tools/commands.h"
#include "tools/engine_flags.h"

namespace flysfm {
namespace {

struct BatchFlags {
  std::vector<std::string> inputs;
  EngineFlags engine;
  int shuffle_seed = -1;
  double interval = 0;
  int max_images = 0;
  bool view_keep = false;
};

int RunOneFolder(const BatchFlags& flags) {
  std::vector<std::string> skipped;
  std::vector<Frame> frames = ListBatchInput(flags.inputs.front(), &skipped);
  for (const std::string& entry : skipped) {
    std::cerr << "flysfm batch: skipped " << entry << "\n";
  }
  if (flags.max_images > 0 && int(frames.size()) > flags.max_images) {
    frames.resize(flags.max_images);
  }
  if (flags.shuffle_seed >= 0) ShuffleFrames(&frames, std::uint32_t(flags.shuffle_seed));
  FrameListSource source(std::move(frames), flags.interval);
  Engine engine = flags.engine.MakeEngine();
  CommandRun run;
  run.skipped_entries = int(skipped.size());
  run.keep_view = flags.view_keep;
  if (flags.interval == 0) run.between_images = RunLoop::Options::BetweenImages::kNothing;
  return RunFromFlags(&source, &engine, flags.engine, run);
}

// One folder per photographer. By EXIF capture time when every image has
// one: a time order that leaves some images out has no place for them, and
// guessing one would mix two orders. Otherwise round robin, each folder in
// name order (a camera's numbering is its shooting order).
int RunSeveralFolders(const BatchFlags& flags) {
  std::vector<std::string> tags;
  std::vector<std::vector<Frame>> folders;
  std::vector<std::string> skipped;
  for (const std::string& input : flags.inputs) {
    if (std::filesystem::exists(std::filesystem::path(input) / "rgb.txt")) {
      throw std::invalid_argument(
          input + " is a TUM sequence: give it alone (its timestamps are one camera's video "
                  "clock, which the rolling-shutter model reads, not a photographer's shots)");
    }
    folders.push_back(ListImageFolder(input, &skipped));
    tags.push_back(SourceTagOfFolder(input));
  }
  for (const std::string& entry : skipped) {
    std::cerr << "flysfm batch: skipped " << entry << "\n";
  }
  tags = UniqueSourceTags(tags);
  MergedSourceOptions merge;
  std::string order;
  if (flags.shuffle_seed >= 0) {
    // Each photographer's own order shuffled; a time order would undo it.
    for (std::size_t i = 0; i < folders.size(); ++i) {
      ShuffleFrames(&folders[i], std::uint32_t(flags.shuffle_seed) + std::uint32_t(i));
    }
    merge.order = MergedSourceOptions::Order::kRoundRobin;
    order = "round robin, each folder shuffled";
  } else {
    int total = 0;
    int untimed = 0;
    std::string first_untimed;
    std::vector<std::vector<std::optional<double>>> times(folders.size());
    for (std::size_t i = 0; i < folders.size(); ++i) {
      for (const Frame& frame : folders[i]) {
        times[i].push_back(ReadCaptureTime(frame));
        ++total;
        if (!times[i].back() && untimed++ == 0) first_untimed = tags[i] + "/" + frame.name;
      }
    }
    if (untimed == 0) {
      for (std::size_t i = 0; i < folders.size(); ++i) {
        for (std::size_t k = 0; k < folders[i].size(); ++k) {
          folders[i][k].timestamp = *times[i][k];
        }
        // The merge takes each folder's frames in time order.
        std::stable_sort(folders[i].begin(), folders[i].end(),
                         [](const Frame& a, const Frame& b) { return a.timestamp < b.timestamp; });
      }
      merge.order = MergedSourceOptions::Order::kCaptureTime;
      order = "by EXIF capture time";
    } else {
      merge.order = MergedSourceOptions::Order::kRoundRobin;
      order = "round robin in name order (" + std::to_string(untimed) + " of " +
              std::to_string(total) + " images have no EXIF capture time, " + first_untimed +
              " the first)";
    }
  }
  std::vector<std::unique_ptr<FrameListSource>> sources;
  std::vector<MergedSource::Input> inputs;
  std::cout << "batch: " << folders.size() << " photographers:";
  for (std::size_t i = 0; i < folders.size(); ++i) {
    std::cout << (i == 0 ? " " : ", ") << tags[i] << " (" << folders[i].size() << " images)";
    // Each photographer shoots at the interval: n of them give n images
    // per interval, as n cameras would.
    sources.push_back(std::make_unique<FrameListSource>(std::move(folders[i]), flags.interval));
    inputs.push_back({tags[i], sources.back().get()});
  }
  std::cout << "; interleaved " << order << "\n" << std::flush;
  MergedSource merged(std::move(inputs), merge);
  LimitedSource limited(&merged, flags.max_images > 0 ? flags.max_images : -1);
  Engine engine = flags.engine.MakeEngine();
  CommandRun run;
  run.skipped_entries = int(skipped.size());
  run.keep_view = flags.view_keep;
  run.sources = tags;
  if (flags.interval == 0) run.between_images = RunLoop::Options::BetweenImages::kNothing;
  return RunFromFlags(&limited, &engine, flags.engine, run);
}

}  // namespace

void AddBatchCommand(CLI::App& app) {
  auto flags = std::make_shared<BatchFlags>();
  CLI::App* command = app.add_subcommand(
      "batch", "Process a folder of photos or a TUM RGB-D sequence folder (rgb.txt), "
               "image by image, with the same per-image results as live capture; several "
               "folders (one per photographer) are interleaved as the shots were taken");
  command
      ->add_option("input", flags->inputs,
                   "Image folder or TUM sequence folder; or several image folders, one per "
                   "photographer, whose images are then named FOLDER/IMAGE (FOLDER: the "
                   "folder's base name, made unique with -2, -3, ...)")
      ->required()
      ->expected(1, -1);
  AddEngineFlags(command, &flags->engine);
  command->add_option("--shuffle", flags->shuffle_seed,
                      "Feed the images in a random order from this seed (any capture "
                      "order must work); -1 keeps the name / rgb.txt order. Several folders: "
                      "each folder's order is shuffled and they take turns")
      ->capture_default_str();
  command->add_option("--interval", flags->interval,
                      "Hand images to the engine this many seconds apart, like a camera; "
                      "several folders: each folder at this pace, like one camera each")
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
      exit_code = flags->inputs.size() == 1 ? RunOneFolder(*flags) : RunSeveralFolders(*flags);
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
