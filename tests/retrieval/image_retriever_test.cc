#include "retrieval/image_retriever.h"

#include <set>
#include <sstream>
#include <stdexcept>

#include <catch2/catch.hpp>

#include "tests/retrieval/place_features.h"

namespace flysfm {
namespace {

ImageRetrieverOptions SmallOptions() {
  ImageRetrieverOptions options;
  options.training.vlad.num_words = 8;
  options.training.vlad.pca_dim = 32;
  options.bootstrap_freeze_images = 16;
  options.min_tree_images = 32;
  options.num_candidates = 5;
  return options;
}

// Image i shows place i % num_places.
void Feed(testing::PlaceFeatures& places, int num_places, int count, ImageRetriever* retriever) {
  for (int i = retriever->NumImages(); i < count; ++i) {
    const FeatureSet features = places.View(i % num_places);
    const RetrievalDescriptor descriptor = retriever->Describe(cv::Mat(), features);
    retriever->Query(descriptor);
    retriever->Insert(i, cv::Mat(), features, descriptor);
  }
}

TEST_CASE("bootstrapped retrieval retrains on a geometric schedule") {
  testing::PlaceFeatures places(10, 4);
  ImageRetriever retriever(SmallOptions());
  CHECK(retriever.bootstrapped());
  // Before any image there is nothing to describe with and nothing to find.
  const RetrievalDescriptor none = retriever.Describe(cv::Mat(), places.View(0));
  CHECK(none.vector.size() == 0);
  CHECK(retriever.Query(none).empty());

  Feed(places, 10, 200, &retriever);
  CHECK(retriever.NumImages() == 200);
  // VLAD trained at 1, 2, 4, 8 and 16 images, then frozen.
  CHECK(retriever.num_model_trainings() == 5);
  CHECK(retriever.generation() == 5);
  // Tree built at 32, 64 and 128 images.
  CHECK(retriever.uses_tree());
  CHECK(retriever.num_tree_builds() == 3);
}

TEST_CASE("bootstrapped retrieval finds the views of the same place") {
  testing::PlaceFeatures places(10, 5);
  ImageRetriever retriever(SmallOptions());
  Feed(places, 10, 120, &retriever);
  // Each place has 11 other views; the top-5 must all be of the same place.
  int correct = 0, total = 0;
  for (image_t i = 0; i < 120; ++i) {
    const auto top = retriever.QueryInserted(i, 5);
    REQUIRE(top.size() == 5);
    for (const auto& c : top) {
      REQUIRE(c.image_id != i);
      correct += c.image_id % 10 == i % 10;
      ++total;
    }
  }
  CHECK(correct == total);
}

TEST_CASE("a stale descriptor and a repeated id are rejected") {
  testing::PlaceFeatures places(3, 6);
  ImageRetriever retriever(SmallOptions());
  const FeatureSet a = places.View(0), b = places.View(1);
  const RetrievalDescriptor first = retriever.Describe(cv::Mat(), a);
  retriever.Insert(0, cv::Mat(), a, first);  // trains: generation 1
  CHECK_THROWS_AS(retriever.Query(first), std::invalid_argument);
  const RetrievalDescriptor second = retriever.Describe(cv::Mat(), b);
  CHECK(retriever.Query(second).size() == 1);
  CHECK_THROWS_AS(retriever.Insert(0, cv::Mat(), b, second), std::invalid_argument);
  CHECK_THROWS_AS(retriever.QueryInserted(7, 3), std::invalid_argument);
}

TEST_CASE("trained mode uses the given model and never retrains") {
  testing::PlaceFeatures places(10, 7);
  std::vector<FeatureSet> training;
  for (int i = 0; i < 40; ++i) training.push_back(places.View(i % 10));
  std::vector<const FeatureSet*> pointers;
  for (const FeatureSet& f : training) pointers.push_back(&f);
  const ImageRetrieverOptions options = SmallOptions();
  auto model = std::make_shared<const RetrievalModel>(TrainRetrievalModel(pointers, options.training));
  ImageRetriever retriever(options, model);
  CHECK_FALSE(retriever.bootstrapped());
  Feed(places, 10, 60, &retriever);
  CHECK(retriever.num_model_trainings() == 0);
  CHECK(retriever.generation() == 0);
  for (image_t i = 0; i < 60; ++i) {
    for (const auto& c : retriever.QueryInserted(i, 5)) REQUIRE(c.image_id % 10 == i % 10);
  }
  // A tree of another dimension does not fit the extractor.
  auto other_tree = std::make_shared<const VocabularyTree>(
      VocabularyTree::Train(RowMatrixXf::Random(50, 7), VocabularyTreeOptions()));
  auto extractor = std::shared_ptr<const GlobalDescriptorExtractor>(model, &model->vlad);
  CHECK_THROWS_AS(ImageRetriever(options, extractor, other_tree), std::invalid_argument);
}

}  // namespace
}  // namespace flysfm

namespace flysfm {

TEST_CASE("a retriever restored from its checkpoint answers and learns as the original") {
  // Views are drawn anew at each call: both retrievers get the same ones,
  // as the engine keeps each image's features.
  testing::PlaceFeatures places(10, 4);
  std::vector<FeatureSet> views;
  for (int i = 0; i < 80; ++i) views.push_back(places.View(i % 10));
  const auto feed = [&](int begin, int end, ImageRetriever* retriever) {
    for (int i = begin; i < end; ++i) {
      retriever->Insert(i, cv::Mat(), views[i], retriever->Describe(cv::Mat(), views[i]));
    }
  };
  // Stopped before the model froze (features retained), after it froze with
  // an exhaustive index, and with a tree.
  for (const int stop : {6, 20, 40}) {
    INFO("stopped after " << stop << " images");
    ImageRetriever original(SmallOptions());
    feed(0, stop, &original);
    std::stringstream checkpoint, model;
    original.Write(checkpoint);
    original.WriteModel(model);
    ImageRetriever restored(SmallOptions());
    restored.Read(checkpoint, &model,
                  [&](image_t id) -> const FeatureSet& { return views.at(id); });
    CHECK(restored.NumImages() == original.NumImages());
    CHECK(restored.generation() == original.generation());
    CHECK(restored.uses_tree() == original.uses_tree());
    // Both go on: same retrainings, same answers.
    feed(stop, 80, &original);
    feed(stop, 80, &restored);
    CHECK(restored.num_model_trainings() == original.num_model_trainings());
    CHECK(restored.num_tree_builds() == original.num_tree_builds());
    for (image_t i = 0; i < 80; i += 7) {
      const auto a = original.QueryInserted(i, 5);
      const auto b = restored.QueryInserted(i, 5);
      REQUIRE(a.size() == b.size());
      for (std::size_t k = 0; k < a.size(); ++k) {
        CHECK(a[k].image_id == b[k].image_id);
        CHECK(a[k].distance == b[k].distance);
      }
    }
  }
}

TEST_CASE("a retriever refuses a checkpoint of the other mode or cut short") {
  testing::PlaceFeatures places(10, 4);
  ImageRetriever original(SmallOptions());
  Feed(places, 10, 20, &original);
  std::ostringstream written, model;
  original.Write(written);
  original.WriteModel(model);
  const auto no_features = [](image_t) -> const FeatureSet& {
    throw std::runtime_error("no features");
  };
  for (const double fraction : {0.0, 0.5, 0.99}) {
    std::istringstream cut(written.str().substr(0, std::size_t(fraction * written.str().size())));
    std::istringstream whole_model(model.str());
    ImageRetriever restored(SmallOptions());
    CHECK_THROWS_AS(restored.Read(cut, &whole_model, no_features), std::runtime_error);
  }
  // The state without its model, or with the model cut short.
  for (const double fraction : {-1.0, 0.5}) {
    std::istringstream state(written.str());
    std::istringstream cut_model(model.str().substr(0, std::size_t(fraction * model.str().size())));
    ImageRetriever restored(SmallOptions());
    CHECK_THROWS_AS(restored.Read(state, fraction < 0 ? nullptr : &cut_model, no_features),
                    std::runtime_error);
  }
}

}  // namespace flysfm
