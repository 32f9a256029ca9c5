#pragma once

// What a run leaves in its output folder, kept current as images arrive:
//   log.jsonl     one ImageResult per line, appended as it happens
//   sparse/       the model in COLMAP text and binary format
//   points.ply    the coloured points
//   trajectory.txt  the registered poses, TUM format (camera-to-world)
//   summary.json  counts, accuracy and stage timings of the run so far
// Every file but the log is replaced atomically.

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/engine.h"

namespace flysfm {

nlohmann::json ToJson(const ImageResult& result);

class RunWriter {
 public:
  // Creates `out_dir`. A fresh run starts an empty log; `resume` appends.
  explicit RunWriter(const std::filesystem::path& out_dir, bool resume = false);

  void Log(const ImageResult& result);
  void WriteModel(const Reconstruction& reconstruction);
  // `results`: every result logged so far; `num_input`: images received.
  void WriteSummary(const Reconstruction& reconstruction,
                    const std::vector<ImageResult>& results, int num_input,
                    const std::vector<std::string>& pending, double wall_seconds);

  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
  std::ofstream log_;
};

// Median and 95th percentile of each stage's time over the results of
// images that were processed (not rejected), in ms.
nlohmann::json StageTimeStatistics(const std::vector<ImageResult>& results);

}  // namespace flysfm
