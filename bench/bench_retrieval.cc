// Retrieval benchmark: query time of the vocabulary-tree and exhaustive
// indexes at 1 000, 10 000 and 100 000 images, the tree's top-30 overlap with
// the exhaustive top-30, and SIFT + global descriptor time per 640x480 TUM
// frame. Prints figures, then one line of JSON.
//
// Descriptors are synthetic but structured like real ones: 256-D unit
// vectors around 1 000 "places" (images of one place are near each other),
// the tree trained on 20 000 of them. Queries are fresh images of random
// places, so their exact neighbours are not trivially themselves.

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "io/sources/image_source.h"
#include "matching/image_decode.h"
#include "retrieval/image_index.h"
#include "retrieval/retrieval_model.h"
#include "tests/testing/data.h"

namespace flysfm {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

class DescriptorSource {
 public:
  explicit DescriptorSource(int dim) : dim_(dim), rng_(1) {
    for (int p = 0; p < 1000; ++p) places_.push_back(Unit());
  }
  Eigen::VectorXf Next() {
    const int place = std::uniform_int_distribution<int>(0, int(places_.size()) - 1)(rng_);
    return (places_[place] + 0.8f * Unit()).normalized();
  }

 private:
  Eigen::VectorXf Unit() {
    std::normal_distribution<float> normal(0.f, 1.f);
    Eigen::VectorXf v(dim_);
    for (int d = 0; d < dim_; ++d) v[d] = normal(rng_);
    return v.normalized();
  }
  int dim_;
  std::mt19937 rng_;
  std::vector<Eigen::VectorXf> places_;
};

struct IndexFigures {
  int size = 0;
  double tree_query_ms = 0;
  double exhaustive_query_ms = 0;
  double top30_overlap = 0;
  double top1_agreement = 0;
};

std::vector<IndexFigures> BenchIndexes() {
  constexpr int kDim = 256;
  constexpr int kQueries = 200;
  DescriptorSource source(kDim);
  RowMatrixXf training(20000, kDim);
  for (int i = 0; i < training.rows(); ++i) training.row(i) = source.Next().transpose();
  auto start = Clock::now();
  auto tree = std::make_shared<const VocabularyTree>(
      VocabularyTree::Train(training, VocabularyTreeOptions()));
  std::printf("tree: %d leaves, trained on %d descriptors in %.0f ms\n", tree->NumLeaves(),
              int(training.rows()), MsSince(start));

  std::vector<IndexFigures> figures;
  VocabularyTreeIndex tree_index(tree);
  ExhaustiveIndex exhaustive(kDim);
  std::vector<Eigen::VectorXf> queries;
  for (int q = 0; q < kQueries; ++q) queries.push_back(source.Next());
  for (const int size : {1000, 10000, 100000}) {
    while (tree_index.Size() < size) {
      const Eigen::VectorXf d = source.Next();
      tree_index.Insert(tree_index.Size(), d);
      exhaustive.Insert(exhaustive.Size(), d);
    }
    IndexFigures f;
    f.size = size;
    std::vector<std::vector<RetrievalCandidate>> tree_results, exact_results;
    start = Clock::now();
    for (const auto& q : queries) tree_results.push_back(tree_index.Query(q, 30));
    f.tree_query_ms = MsSince(start) / kQueries;
    start = Clock::now();
    for (const auto& q : queries) exact_results.push_back(exhaustive.Query(q, 30));
    f.exhaustive_query_ms = MsSince(start) / kQueries;
    for (int q = 0; q < kQueries; ++q) {
      std::set<int> exact;
      for (const auto& c : exact_results[q]) exact.insert(c.image_id);
      for (const auto& c : tree_results[q]) f.top30_overlap += exact.count(c.image_id) / 30.0;
      f.top1_agreement += tree_results[q][0].image_id == exact_results[q][0].image_id;
    }
    f.top30_overlap /= kQueries;
    f.top1_agreement /= kQueries;
    std::printf(
        "%6d images: tree query %.3f ms, exhaustive query %.3f ms, top-30 overlap %.3f, "
        "top-1 agreement %.3f\n",
        size, f.tree_query_ms, f.exhaustive_query_ms, f.top30_overlap, f.top1_agreement);
    figures.push_back(f);
  }
  return figures;
}

struct ExtractionFigures {
  int frames = 0;
  double decode_ms = 0;
  double sift_ms = 0;
  double descriptor_ms = 0;
  double features = 0;
  double opencv_sift_ms = 0;
};

// Per 640x480 TUM frame; the VLAD model is trained on the same frames first
// (its training is not timed: it happens once).
ExtractionFigures BenchExtraction() {
  ExtractionFigures f;
  const std::string sequence = "tum/rgbd_dataset_freiburg1_xyz";
  const std::string rgb_txt = testing::DataPath(sequence + "/rgb.txt");
  if (!std::filesystem::exists(rgb_txt)) {
    std::printf("extraction: skipped, %s not found\n", rgb_txt.c_str());
    return f;
  }
  const std::vector<Frame> frames = ListTumSequence(testing::DataPath(sequence));
  std::vector<cv::Mat> images;
  for (std::size_t i = 0; i < frames.size() && images.size() < 30; i += 10) {
    const auto start = Clock::now();
    const DecodedImage decoded = DecodeImageFile(frames[i].path.string());
    f.decode_ms += MsSince(start);
    if (decoded.ok()) images.push_back(decoded.image);
  }
  f.frames = int(images.size());
  if (f.frames == 0) return f;
  std::vector<FeatureSet> features;
  const SiftOptions sift;
  // One untimed warm-up (OpenCV's thread pool, first allocations).
  ExtractFeatures(images[0], sift);
  auto start = Clock::now();
  for (const cv::Mat& image : images) features.push_back(ExtractFeatures(image, sift));
  f.sift_ms = MsSince(start) / f.frames;
  // Reference under the same machine load: OpenCV's SIFT alone on the grey
  // frame, uncapped (docs/peers.md: 53 ms on an idle machine).
  cv::Ptr<cv::SIFT> sift_alone = cv::SIFT::create();
  start = Clock::now();
  for (const cv::Mat& image : images) {
    cv::Mat grey;
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
    std::vector<cv::KeyPoint> keypoints;
    cv::Mat descriptors;
    sift_alone->detectAndCompute(grey, cv::noArray(), keypoints, descriptors);
  }
  f.opencv_sift_ms = MsSince(start) / f.frames;
  std::vector<const FeatureSet*> pointers;
  for (const FeatureSet& fs : features) {
    pointers.push_back(&fs);
    f.features += double(fs.size()) / f.frames;
  }
  const VladExtractor vlad = VladExtractor::Train(pointers, VladOptions());
  start = Clock::now();
  for (const FeatureSet& fs : features) vlad.Compute(fs);
  f.descriptor_ms = MsSince(start) / f.frames;
  f.decode_ms /= f.frames;
  std::printf(
      "extraction per 640x480 frame (%d frames, %.0f features): decode %.1f ms, SIFT + RootSIFT "
      "%.1f ms, VLAD (%d-D) %.1f ms; extraction + global descriptor %.1f ms (OpenCV SIFT "
      "alone, same load: %.1f ms)\n",
      f.frames, f.features, f.decode_ms, f.sift_ms, vlad.Dim(), f.descriptor_ms,
      f.sift_ms + f.descriptor_ms, f.opencv_sift_ms);
  return f;
}

}  // namespace
}  // namespace flysfm

int main() {
  const auto indexes = flysfm::BenchIndexes();
  const auto extraction = flysfm::BenchExtraction();
  std::printf("{\"bench\":\"retrieval\"");
  for (const auto& f : indexes) {
    std::printf(",\"tree_query_ms_%d\":%.4f,\"exhaustive_query_ms_%d\":%.4f,\"top30_overlap_%d\":%.3f",
                f.size, f.tree_query_ms, f.size, f.exhaustive_query_ms, f.size, f.top30_overlap);
  }
  std::printf(",\"frames\":%d,\"decode_ms\":%.2f,\"sift_ms\":%.2f,\"global_descriptor_ms\":%.2f,"
              "\"extraction_plus_descriptor_ms\":%.2f,\"opencv_sift_alone_ms\":%.2f}\n",
              extraction.frames, extraction.decode_ms, extraction.sift_ms,
              extraction.descriptor_ms, extraction.sift_ms + extraction.descriptor_ms,
              extraction.opencv_sift_ms);
  return 0;
}
