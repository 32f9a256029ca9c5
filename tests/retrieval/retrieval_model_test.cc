#include "retrieval/retrieval_model.h"

#include <filesystem>
#include <fstream>
#include <stdexcept>

#include <catch2/catch.hpp>
#include <opencv2/imgcodecs.hpp>

#include "io/synthetic/procedural_texture.h"
#include "tests/retrieval/place_features.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

RetrievalTrainingOptions SmallOptions() {
  RetrievalTrainingOptions options;
  options.vlad.num_words = 8;
  options.vlad.pca_dim = 32;
  return options;
}

TEST_CASE("a retrieval model saves and loads exactly") {
  testing::PlaceFeatures places(40, 3);
  std::vector<FeatureSet> views;
  for (int p = 0; p < 40; ++p) views.push_back(places.View(p));
  std::vector<const FeatureSet*> training;
  for (const FeatureSet& f : views) training.push_back(&f);
  const RetrievalModel model = TrainRetrievalModel(training, SmallOptions());
  CHECK(model.tree.Dim() == model.vlad.Dim());
  // Trained on 40 images x 9 samples: more than one leaf.
  CHECK(model.tree.NumLeaves() > 5);

  const std::string path = (testing::MakeTempDir("retrieval_model_test") / "model.bin").string();
  model.Save(path);
  const RetrievalModel loaded = RetrievalModel::Load(path);
  CHECK(loaded.vlad == model.vlad);
  CHECK(loaded.tree == model.tree);

  // Truncated, and a tree file where a model file is expected.
  const auto size = fs::file_size(path);
  fs::resize_file(path, size / 2);
  CHECK_THROWS_AS(RetrievalModel::Load(path), std::runtime_error);
  model.tree.Save(path);
  CHECK_THROWS_AS(RetrievalModel::Load(path), std::runtime_error);
  fs::remove(path);
  CHECK_THROWS_AS(RetrievalModel::Load(path), std::runtime_error);
}

TEST_CASE("training from files skips undecodable ones and fails with none usable") {
  const fs::path dir = testing::MakeTempDir("retrieval_model_files");
  for (int i = 0; i < 3; ++i) {
    REQUIRE(cv::imwrite((dir / ("t" + std::to_string(i) + ".png")).string(),
                        MakeTexture(320, 240, 20 + i)));
  }
  std::ofstream((dir / "broken.jpg").string()) << "not a jpeg";
  std::vector<std::string> paths;
  for (const auto& entry : fs::directory_iterator(dir)) paths.push_back(entry.path().string());
  RetrievalTrainingReport report;
  const RetrievalModel model = TrainRetrievalModelFromFiles(paths, SmallOptions(), &report);
  CHECK(report.num_images == 3);
  CHECK(report.skipped.size() == 1);
  CHECK(report.num_features > 300);
  CHECK(model.vlad.NumWords() == 8);

  CHECK_THROWS_AS(TrainRetrievalModelFromFiles({(dir / "broken.jpg").string()}, SmallOptions()),
                  std::invalid_argument);
}

}  // namespace
}  // namespace flysfm
