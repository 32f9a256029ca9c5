// flysfm train-retrieval: trains the retrieval model (VLAD codebook,
// PCA-whitening, vocabulary tree) from the images of some folders and writes
// it to one file, for the engine's trained mode (docs/retrieval.md).

#include <chrono>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "matching/image_decode.h"
#include "retrieval/retrieval_model.h"
#include "tools/commands.h"

namespace flysfm {
namespace {

struct TrainRetrievalArgs {
  std::vector<std::string> image_dirs;
  std::string out;
  RetrievalTrainingOptions options;
};

int RunTrainRetrieval(const TrainRetrievalArgs& args) {
  std::vector<std::string> paths;
  for (const std::string& dir : args.image_dirs) {
    const std::vector<std::string> files = ListImageFiles(dir);
    std::cout << dir << ": " << files.size() << " images\n";
    paths.insert(paths.end(), files.begin(), files.end());
  }
  const auto start = std::chrono::steady_clock::now();
  RetrievalTrainingReport report;
  const RetrievalModel model = TrainRetrievalModelFromFiles(paths, args.options, &report);
  for (const std::string& reason : report.skipped) std::cerr << "skipped: " << reason << "\n";
  model.Save(args.out);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << "trained on " << report.num_images << " images (" << report.num_features
            << " features) in " << seconds << " s: " << model.vlad.NumWords()
            << " words, descriptor dimension " << model.vlad.Dim() << ", tree of "
            << model.tree.NumLeaves() << " leaves\n"
            << "wrote " << args.out << "\n";
  return 0;
}

}  // namespace

void AddTrainRetrievalCommand(CLI::App& app) {
  auto args = std::make_shared<TrainRetrievalArgs>();
  CLI::App* command = app.add_subcommand(
      "train-retrieval",
      "Train the retrieval model (VLAD codebook, PCA-whitening, vocabulary tree) from the "
      "images directly inside the given folders, for the engine's trained mode.");
  command->add_option("--images", args->image_dirs, "Folders of training images")
      ->required()
      ->check(CLI::ExistingDirectory);
  command->add_option("--out", args->out, "Model file to write")->required();
  RetrievalTrainingOptions& o = args->options;
  command->add_option("--max-features", o.sift.max_num_features, "SIFT features per image")
      ->capture_default_str();
  command->add_option("--max-image-size", o.sift.max_image_size,
                      "Longest image side for extraction (px)")
      ->capture_default_str();
  command->add_option("--words", o.vlad.num_words, "VLAD codebook size")->capture_default_str();
  command->add_option("--pca-dim", o.vlad.pca_dim, "Global descriptor dimension")
      ->capture_default_str();
  command->add_option("--crops", o.vlad.crops_per_image, "Random crops per training image")
      ->capture_default_str();
  command->add_option("--branching", o.tree.branching, "Vocabulary tree branching")
      ->capture_default_str();
  command->add_option("--depth", o.tree.depth, "Vocabulary tree depth")->capture_default_str();
  command->add_option("--seed", o.vlad.seed, "Random seed")->capture_default_str();
  command->callback([args]() {
    args->options.tree.seed = args->options.vlad.seed;
    if (!args->options.Check()) throw CLI::ValidationError("train-retrieval", "invalid options");
    try {
      RunTrainRetrieval(*args);
    } catch (const std::exception& e) {
      throw CLI::RuntimeError(std::string("train-retrieval: ") + e.what(), 1);
    }
  });
}

}  // namespace flysfm
