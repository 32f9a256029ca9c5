#pragma once

// What a run leaves in its output folder, kept current as images arrive:
//   log.jsonl     one ImageResult per line, appended as it happens
//   sparse/       the model in COLMAP text and binary format
//   points.ply    the coloured points, with their quality measures
//   trajectory.txt  the registered poses, TUM format (camera-to-world)
//   summary.json  counts, accuracy, stage timings and quality of the run so far
// Every file but the log is replaced atomically. The log is appended to
// across runs on the same folder. The model files and the summary a previous
// run left are replaced only once this run's model has at least as many
// registered images (MayReplaceOutputs): a restart's first images never
// overwrite a larger model.

#include <filesystem>
#include <optional>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/engine.h"
#include "quality/coverage.h"
#include "quality/quality_tracker.h"

namespace flysfm {

nlohmann::json ToJson(const ImageResult& result);
// summary.json's "refinement".
nlohmann::json ToJson(const Engine::RefinementTotals& totals);
// summary.json's "quality": the tracker's summary, its options, and per
// registered image its name, inliers, spread and centre sigma (null when
// undefined).
nlohmann::json ToJson(const QualityTracker& quality, const Reconstruction& reconstruction);
// summary.json's "coverage": the surface's areas and share, and the
// suggested viewpoints.
nlohmann::json ToJson(const Coverage& coverage);

// One photographer's share of a run fed by several sources
// (io/sources/merged_source.h): summary.json's "sources". Each count is the
// run's own count restricted to the source's images, so that they add up to
// it over the sources.
struct SourceCounts {
  std::string tag;
  int images_in = 0;   // frames of this source the engine took
  int registered = 0;  // its images registered in the model
  int rejected = 0;    // its rejected results
  int pending = 0;     // its images waiting
};

// What summary.json counts besides the engine's results.
struct RunCounts {
  int images_in = 0;        // frames the source handed on
  int quarantined = 0;      // not given to the engine: quarantined earlier
  int engine_errors = 0;    // the engine threw on them; now quarantined
  int write_errors = 0;     // output writes that failed (the next one retries)
  int skipped_entries = 0;  // input folder entries that could not be examined
  int resumed_images = 0;   // images the checkpointed model held at the start
  int in_model = 0;         // frames skipped as the resumed model held them
  double checkpoint_ms = 0; // writing the checkpoint, in all
  Engine::RefinementTotals refinement;
  // Per source, in the sources' order; empty for a single source.
  std::vector<SourceCounts> sources;
};

class RunWriter {
 public:
  // Creates `out_dir` and opens its log for appending. Notes how many
  // registered images the model a previous run left there has (its
  // summary.json).
  explicit RunWriter(const std::filesystem::path& out_dir);

  // `source`: the tag of the source the image came from (a "source" field
  // on its record); empty for a single source, and then no field.
  // `coverage_ms`: the coverage surface's update, as "coverage" in "ms".
  // `quality_ms`: the quality tracker's update for this record, as "quality"
  // in its "ms" (outside "total", which is the engine's); none without it.
  void Log(const ImageResult& result, const std::string& source = "",
           std::optional<double> quality_ms = std::nullopt,
           std::optional<double> coverage_ms = std::nullopt);
  // Whether the model files and summary may be written now: false while
  // `reconstruction` has fewer registered images than a previous run's
  // model in the folder. `final` (the run's last write) makes it true, the
  // previous model files and summary then moved to OUT/previous/ first.
  bool MayReplaceOutputs(const Reconstruction& reconstruction, bool final);
  // `quality`, when given, must be current: its measures go into points.ply.
  // `coverage`, when given, is written as surface.ply.
  void WriteModel(const Reconstruction& reconstruction,
                  const QualityTracker* quality = nullptr, const Coverage* coverage = nullptr);
  // `results`: every result logged so far. `quality`, when given and
  // current, becomes the "quality" object.
  void WriteSummary(const Reconstruction& reconstruction,
                    const std::vector<ImageResult>& results, const RunCounts& counts,
                    const std::vector<std::string>& pending, double wall_seconds,
                    const QualityTracker* quality = nullptr,
                    const Coverage* coverage = nullptr);

  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
  std::ofstream log_;
  // The previous run's registered images, until this run's outputs replace
  // its outputs (then 0).
  std::size_t previous_registered_ = 0;
};

// Median and 95th percentile of each stage's time over the results of
// images that were processed (not rejected), in ms.
nlohmann::json StageTimeStatistics(const std::vector<ImageResult>& results);

}  // namespace flysfm
