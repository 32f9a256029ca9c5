#include "io/run/run_loop.h"

#include <algorithm>
#include <cstring>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <unordered_set>

#include "geometry/statistics.h"
#include "io/run/progress_line.h"
#include "io/sources/quarantine.h"
#include "io/view/view_server.h"

namespace flysfm {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

void PrintLine(std::FILE* out, int index, const ImageResult& result,
               std::optional<double> delay_ms) {
  char delay[48] = "";
  if (delay_ms) std::snprintf(delay, sizeof(delay), "  delay %6.0f ms", *delay_ms);
  // Which sub-model, once there are several or a shot merged some.
  char models[64] = "";
  if (result.num_models > 1 || result.num_merged_models > 0) {
    std::snprintf(models, sizeof(models), " in %d sub-model%s", result.num_models,
                  result.num_models == 1 ? "" : "s");
    if (result.model_id != kInvalidModelId) {
      std::snprintf(models + std::strlen(models), sizeof(models) - std::strlen(models),
                    ", this in %u", result.model_id);
    }
    if (result.num_merged_models > 0) {
      std::snprintf(models + std::strlen(models), sizeof(models) - std::strlen(models),
                    ", %d merged", result.num_merged_models);
    }
  }
  std::fprintf(out,
               "[%4d] %-32s %-10s %6d pts %+5d new %7.0f ms  model %d img / %d pts%s%s%s%s\n",
               index, result.name.c_str(), ImageStatusName(result.status),
               result.num_observations, result.num_new_points, result.times.total,
               result.model_images, result.model_points, models, delay,
               result.reason.empty() ? "" : "  ", result.reason.c_str());
  std::fflush(out);
}

// What `step` threw, whatever it was (a std::logic_error of a broken
// invariant included); nullopt when it returned.
std::optional<std::string> ErrorOf(const std::function<void()>& step) {
  try {
    step();
  } catch (const std::exception& e) {
    return std::string(e.what());
  } catch (...) {
    return std::string("unknown exception");
  }
  return std::nullopt;
}

// One run's state: what the loop's steps share.
class RunState {
 public:
  RunState(const RunLoop::Options& options, ViewServer* view, Engine* engine,
      const RunLoop::Hooks& hooks)
      : options_(options), view_(view), engine_(engine), hooks_(hooks), start_(Clock::now()) {
    if (!options_.out.empty()) {
      writer_ = std::make_unique<RunWriter>(options_.out);
      quality_ = std::make_unique<QualityTracker>(options_.quality);
      if (options_.coverage) {
        Coverage::Options coverage = options_.coverage_options;
        // One rule of "well covered", the points'.
        coverage.min_views = options_.quality.min_views;
        coverage.min_angle_deg = options_.quality.min_angle_deg;
        coverage_ = std::make_unique<Coverage>(coverage);
      }
      checkpointer_ = std::make_unique<Checkpointer>(
          std::filesystem::path(options_.out) / "state", options_.checkpoint);
    }
    summary_.counts.skipped_entries = options_.skipped_entries;
  }

  RunLoop::Summary Go(ImageSource* source);

 private:
  void Resume();
  // `quality_ms`, `coverage_ms`: the quality and coverage updates after the
  // step that gave `results`, logged on the arriving image's record (else
  // the first).
  void Report(const std::vector<ImageResult>& results, RunLoop::Origin origin,
              const std::string& arriving = "", std::optional<double> quality_ms = std::nullopt,
              std::optional<double> coverage_ms = std::nullopt);
  // Measures the coverage surface again when the model changed since, and
  // (unless `now`) refresh_seconds have passed since the last time: its
  // time in ms, 0 when not due (nullopt without coverage).
  std::optional<double> UpdateCoverage(bool now);
  // Takes the model's changes once for both consumers: updates the quality
  // tracker and keeps them for the view's next update. The tracker's time,
  // in ms (nullopt without a tracker). `flush`: also what waits from the
  // tracker's refresh budget (the end of the run).
  std::optional<double> TakeChanges(bool flush = false);
  void PublishView();
  void Checkpoint(double call_ms, bool final);
  bool WriteOutputs(bool final);
  void RefreshOutputs();
  void ProcessImage(PreparedFrame frame);
  void RefineWhileIdle(const PreparedFrameSource& prepared);
  void End();
  // Tells what the end is doing: a progress line on stdout, the view's status.
  void ShowEnd(const std::string& step, const std::string& detail, double elapsed_s,
               std::optional<double> remaining_s);
  void PrintClosingLines() const;
  // The tag of the source image `name` came from; empty for a single source.
  std::string SourceOf(const std::string& name) const;
  std::vector<SourceCounts> CountBySource() const;

  const RunLoop::Options& options_;
  ViewServer* view_;
  Engine* engine_;
  const RunLoop::Hooks& hooks_;
  const Clock::time_point start_;
  Clock::time_point last_refresh_ = start_;
  std::unique_ptr<RunWriter> writer_;
  std::unique_ptr<Checkpointer> checkpointer_;
  std::unique_ptr<QualityTracker> quality_;
  std::unique_ptr<Coverage> coverage_;
  Clock::time_point last_coverage_;
  bool model_changed_since_coverage_ = true;
  bool coverage_unpublished_ = false;
  // Changes taken since the view's last update.
  Reconstruction::Changes view_changes_;
  std::unique_ptr<Quarantine> quarantine_;
  std::unique_ptr<QuarantineFilterSource> filtered_;
  std::unique_ptr<ProgressLine> progress_;
  std::unordered_set<std::string> in_model_;
  RunLoop::Summary summary_;
  std::vector<ImageResult> logged_;  // what summary.json summarises
  std::vector<ViewLine> view_lines_;
  // A pending image's later result is timed from its own arrival.
  std::map<std::string, Clock::time_point> arrivals_;
  // Image name -> its source's tag, and frames taken per tag, as frames
  // arrive with one.
  std::map<std::string, std::string> sources_;
  std::map<std::string, int> images_in_by_source_;
  std::vector<double> registration_delays_ms_;
  double engine_ms_ = 0;
  bool refinement_failed_ = false;
  bool source_failed_ = false;
};

void RunState::Resume() {
  if (!checkpointer_) return;
  if (!options_.resume || !checkpointer_->Exists()) {
    checkpointer_->Clear();
    return;
  }
  try {
    checkpointer_->Restore(engine_);
  } catch (const std::exception& e) {
    throw std::runtime_error("cannot resume from " + checkpointer_->dir().string() + ": " +
                             e.what() + "; move that folder away to start the model over");
  }
  for (const auto& [image_id, image] : engine_->reconstruction().images()) {
    in_model_.insert(image.name);
  }
  summary_.counts.resumed_images = int(in_model_.size());
  if (options_.print) {
    std::fprintf(options_.output, "resumed: %zu images (%zu registered, %zu points) from %s in %.1f s\n",
                in_model_.size(), engine_->reconstruction().NumRegisteredImages(),
                engine_->reconstruction().NumPoints3D(), checkpointer_->dir().c_str(),
                SecondsSince(start_));
    std::fflush(options_.output);
  }
}

void RunState::Report(const std::vector<ImageResult>& results, RunLoop::Origin origin,
                      const std::string& arriving, std::optional<double> quality_ms,
                      std::optional<double> coverage_ms) {
  std::size_t quality_owner = 0;
  for (std::size_t i = 0; i < results.size(); ++i) {
    if (!arriving.empty() && results[i].name == arriving) quality_owner = i;
  }
  for (std::size_t i = 0; i < results.size(); ++i) {
    const ImageResult& result = results[i];
    RunLoop::Reported reported{result, origin, !arriving.empty() && result.name == arriving,
                               std::nullopt};
    const auto arrival = arrivals_.find(result.name);
    if (arrival != arrivals_.end() && arrival->second != Clock::time_point()) {
      reported.delay_ms = 1000 * SecondsSince(arrival->second);
      if (result.status == ImageStatus::kRegistered) {
        registration_delays_ms_.push_back(*reported.delay_ms);
      }
    }
    const std::optional<double> shown_delay =
        options_.live ? reported.delay_ms : std::optional<double>();
    if (progress_) progress_->Done();
    if (options_.print) PrintLine(options_.output, summary_.counts.images_in, result, shown_delay);
    const std::string source = SourceOf(result.name);
    if (view_) view_lines_.push_back(MakeViewLine(result, shown_delay, source));
    std::optional<double> logged_quality_ms;
    if (quality_) logged_quality_ms = i == quality_owner ? quality_ms.value_or(0) : 0;
    std::optional<double> logged_coverage_ms;
    if (coverage_) logged_coverage_ms = i == quality_owner ? coverage_ms.value_or(0) : 0;
    if (writer_) writer_->Log(result, source, logged_quality_ms, logged_coverage_ms);
    logged_.push_back(result);
    summary_.results.push_back(std::move(reported));
  }
}

std::optional<double> RunState::TakeChanges(bool flush) {
  if (!quality_ && !view_) return std::nullopt;
  const Reconstruction::Changes changes = engine_->TakeReconstructionChanges();
  if (!changes.empty()) model_changed_since_coverage_ = true;
  if (view_) view_changes_.Merge(changes);
  if (!quality_) return std::nullopt;
  // Points whose measures moved without their positions (an observing
  // image's pose moved): the page's colouring must follow.
  const auto remeasured_to_view = [&] {
    if (!view_) return;
    Reconstruction::Changes remeasured;
    const std::vector<point3D_t>& ids = quality_->LastRecomputedPoints();
    remeasured.changed_points.insert(ids.begin(), ids.end());
    view_changes_.Merge(remeasured);
  };
  double ms = quality_->Update(engine_->reconstruction(), changes);
  remeasured_to_view();
  if (flush) {
    ms += quality_->Flush(engine_->reconstruction());
    remeasured_to_view();
  }
  return ms;
}

// Each step's changes to the model, as the page draws them (docs/view.md).
void RunState::PublishView() {
  if (!view_) return;
  TakeChanges();
  view_->Publish(MakeViewUpdate(engine_->reconstruction(), std::move(view_changes_),
                                std::move(view_lines_), quality_.get(),
                                coverage_unpublished_ ? coverage_.get() : nullptr));
  coverage_unpublished_ = false;
  view_changes_ = Reconstruction::Changes();
  view_lines_.clear();
}

// A failed checkpoint write (a full disk) is counted like any failed
// output; the next one writes what is still missing.
void RunState::Checkpoint(double call_ms, bool final) {
  engine_ms_ += call_ms;
  if (!checkpointer_) return;
  try {
    checkpointer_->Update(*engine_, call_ms, final);
  } catch (const std::exception& e) {
    ++summary_.counts.write_errors;
    std::fprintf(stderr, "cannot write the checkpoint: %s\n", e.what());
  }
  const Checkpointer::Summary& saved = checkpointer_->summary();
  summary_.counts.checkpoint_ms = saved.records_ms + saved.snapshots_ms;
}

// A failed write (a full disk, a folder made read-only) loses no image: the
// engine's model is whole, and the next write tries again.
bool RunState::WriteOutputs(bool final) {
  RunCounts& counts = summary_.counts;
  if (filtered_) {
    counts.quarantined = filtered_->num_skipped();
    counts.in_model = filtered_->num_in_model();
  }
  counts.refinement = engine_->refinement_totals();
  counts.sources = CountBySource();
  if (!writer_) return true;
  try {
    if (!writer_->MayReplaceOutputs(engine_->reconstruction(), final)) return true;
    TakeChanges();
    writer_->WriteModel(engine_->reconstruction(), quality_.get(), coverage_.get());
    writer_->WriteSummary(engine_->reconstruction(), logged_, counts,
                          engine_->PendingImageNames(), SecondsSince(start_), quality_.get(),
                          coverage_.get());
    return true;
  } catch (const std::exception& e) {
    ++counts.write_errors;
    std::fprintf(stderr, "cannot write the outputs in %s: %s\n", options_.out.c_str(), e.what());
    return false;
  }
}

std::optional<double> RunState::UpdateCoverage(bool now) {
  if (!coverage_) return std::nullopt;
  if (!model_changed_since_coverage_) return 0.0;
  // At most every refresh_seconds, and never more than a tenth of the run's
  // time: a slow machine or a sanitizer build measures less often.
  const double interval = std::max(options_.refresh_seconds, 10 * coverage_->summary().ms / 1000);
  if (!now && SecondsSince(last_coverage_) < interval) return 0.0;
  coverage_->Update(engine_->reconstruction());
  last_coverage_ = Clock::now();
  model_changed_since_coverage_ = false;
  coverage_unpublished_ = true;
  return coverage_->summary().ms;
}

void RunState::RefreshOutputs() {
  if (SecondsSince(last_refresh_) < options_.refresh_seconds) return;
  WriteOutputs(/*final=*/false);
  last_refresh_ = Clock::now();
}

void RunState::ProcessImage(PreparedFrame frame) {
  ++summary_.counts.images_in;
  const std::string name = frame.frame.name;
  arrivals_[name] = frame.frame.arrival;
  if (!frame.frame.source.empty()) {
    sources_[name] = frame.frame.source;
    ++images_in_by_source_[frame.frame.source];
  }
  if (view_) view_->SetLatestShot(frame.image, name);
  if (hooks_.on_arrival) hooks_.on_arrival(*engine_, frame);
  if (quarantine_) quarantine_->BeginEngine(name);
  std::vector<ImageResult> results;
  const auto call_start = Clock::now();
  const std::optional<std::string> error = ErrorOf([&] {
    results = hooks_.add_image ? hooks_.add_image(engine_, std::move(frame))
                               : engine_->AddImage(std::move(frame));
  });
  const double call_ms = 1000 * SecondsSince(call_start);
  summary_.calls.push_back({name, call_ms, 0});
  summary_.last_image_s = SecondsSince(start_);
  if (!error) {
    if (quarantine_) quarantine_->Done(name);
  } else {
    ++summary_.counts.engine_errors;
    if (quarantine_) quarantine_->Fail(name, "engine error: " + *error);
    std::fprintf(stderr, "engine error on %s: %s; the image is %s\n", name.c_str(),
                 error->c_str(), quarantine_ ? "quarantined" : "skipped");
    ImageResult failed;
    failed.name = name;
    failed.status = ImageStatus::kRejected;
    failed.reason = "engine error (quarantined): " + *error;
    results.push_back(failed);
  }
  if (hooks_.on_image) hooks_.on_image(*engine_, results, call_ms);
  const std::optional<double> quality_ms = TakeChanges();
  const std::optional<double> coverage_ms = UpdateCoverage(/*now=*/false);
  Report(results, RunLoop::Origin::kArrival, name, quality_ms, coverage_ms);
  const auto checkpoint_start = Clock::now();
  Checkpoint(call_ms, /*final=*/false);
  summary_.calls.back().checkpoint_ms = 1000 * SecondsSince(checkpoint_start);
  PublishView();
  RefreshOutputs();
  if (hooks_.after_image) hooks_.after_image(*engine_);
}

std::string RunState::SourceOf(const std::string& name) const {
  const auto known = sources_.find(name);
  if (known != sources_.end()) return known->second;
  // An image of an earlier run on this folder: a merged name is `<tag>/...`,
  // and a tag holds no '/'.
  for (const std::string& tag : options_.sources) {
    if (name.size() > tag.size() && name.compare(0, tag.size(), tag) == 0 &&
        name[tag.size()] == '/') {
      return tag;
    }
  }
  return {};
}

std::vector<SourceCounts> RunState::CountBySource() const {
  std::vector<SourceCounts> counts;
  std::map<std::string, std::size_t> index;
  const auto of = [&](const std::string& tag) -> SourceCounts* {
    if (tag.empty()) return nullptr;
    const auto [it, added] = index.emplace(tag, counts.size());
    if (added) counts.push_back(SourceCounts{tag});
    return &counts[it->second];
  };
  // Every source given, in its order, then any other a frame named.
  for (const std::string& tag : options_.sources) of(tag);
  for (const auto& [tag, images_in] : images_in_by_source_) of(tag)->images_in = images_in;
  for (const image_t image_id : engine_->reconstruction().RegisteredImageIds()) {
    if (SourceCounts* source = of(SourceOf(engine_->reconstruction().image(image_id).name))) {
      ++source->registered;
    }
  }
  for (const ImageResult& result : logged_) {
    if (result.status != ImageStatus::kRejected) continue;
    if (SourceCounts* source = of(SourceOf(result.name))) ++source->rejected;
  }
  for (const std::string& name : engine_->PendingImageNames()) {
    if (SourceCounts* source = of(SourceOf(name))) ++source->pending;
  }
  return counts;
}

void RunState::RefineWhileIdle(const PreparedFrameSource& prepared) {
  using Between = RunLoop::Options::BetweenImages;
  if (refinement_failed_ || options_.between_images == Between::kNothing) return;
  const std::optional<std::string> error = ErrorOf([&] {
    if (options_.between_images == Between::kRefineToEnd) {
      const std::vector<ImageResult> registered = engine_->RefineToEnd();
      Report(registered, RunLoop::Origin::kRefinement, "", TakeChanges());
      PublishView();
      return;
    }
    RefineUntilNextFrame(engine_, prepared, options_.refinement_share,
                         [&](Engine::RefinementSlice* slice) {
                           Report(slice->registered, RunLoop::Origin::kRefinement, "",
                                  TakeChanges());
                           PublishView();
                           RefreshOutputs();
                         });
  });
  if (error) {
    ++summary_.counts.engine_errors;
    refinement_failed_ = true;
    std::fprintf(stderr, "engine error while refining: %s; no more refinement in this run\n",
                 error->c_str());
  }
}

void RunState::ShowEnd(const std::string& step, const std::string& detail, double elapsed_s,
                       std::optional<double> remaining_s) {
  if (progress_) progress_->Show(step, detail, elapsed_s, remaining_s);
  if (view_) view_->SetStatus(ProgressLine::Format(step, detail, elapsed_s, remaining_s));
}

// "3 of at most 50"
std::string OfAtMost(int value, int bound) {
  return std::to_string(value) + " of at most " + std::to_string(bound);
}

// The source is done: what refinement has left, at once (a second Ctrl-C
// in live quits; the checkpoint holds every image), then Finish. Each step
// says what it does: the end may take minutes.
void RunState::End() {
  const auto end_start = Clock::now();
  if (options_.print) {
    progress_ = std::make_unique<ProgressLine>(options_.output, options_.progress_interval_s);
  }
  if (options_.between_images != RunLoop::Options::BetweenImages::kNothing &&
      !refinement_failed_) {
    int slices = 0;
    const auto on_slice = [&](const Engine::RefinementSlice& slice) {
      ShowEnd("refinement", std::string(Engine::RefinementStepName(slice.step)) + ", slice " +
                                std::to_string(++slices),
              SecondsSince(end_start), std::nullopt);
    };
    if (const std::optional<std::string> error = ErrorOf(
            [&] { Report(engine_->RefineToEnd(on_slice), RunLoop::Origin::kEnd); })) {
      ++summary_.counts.engine_errors;
      std::fprintf(stderr, "engine error while refining: %s\n", error->c_str());
    }
  }
  const auto finish_start = Clock::now();
  const auto on_finish = [&](const Engine::FinishProgress& progress) {
    std::string detail;
    if (progress.step == Engine::FinishProgress::Step::kSnoop) {
      detail = "adjustment " + OfAtMost(progress.round, progress.max_rounds) + ", ";
    }
    if (progress.step != Engine::FinishProgress::Step::kRetry) {
      detail += "iteration " + OfAtMost(progress.iteration, progress.max_iterations);
    }
    ShowEnd(Engine::FinishStepName(progress.step), detail, SecondsSince(end_start),
            progress.remaining_s);
  };
  if (const std::optional<std::string> error = ErrorOf([&] {
        Report(hooks_.finish ? hooks_.finish(engine_, on_finish) : engine_->Finish(on_finish),
               RunLoop::Origin::kEnd);
      })) {
    ++summary_.counts.engine_errors;
    std::fprintf(stderr, "engine error while finishing: %s; the model is written as it is\n",
                 error->c_str());
  }
  summary_.finish_s = SecondsSince(finish_start);
  ShowEnd("writing the final model and checkpoint", "", SecondsSince(end_start), std::nullopt);
  Checkpoint(1000 * SecondsSince(end_start), /*final=*/true);
  // The final files and view hold every measure current.
  TakeChanges(/*flush=*/true);
  UpdateCoverage(/*now=*/true);
  PublishView();
  if (!WriteOutputs(/*final=*/true)) summary_.exit_code = 1;
  if (source_failed_) summary_.exit_code = 1;
  if (progress_) progress_->Done();
  progress_.reset();
  summary_.end_s = SecondsSince(end_start);
  summary_.wall_s = SecondsSince(start_);
  if (checkpointer_) summary_.checkpoint = checkpointer_->summary();
}

void RunState::PrintClosingLines() const {
  const Reconstruction& model = engine_->reconstruction();
  const RunCounts& counts = summary_.counts;
  std::fprintf(options_.output, "done: %d images in, %zu registered, %d rejected, %zu pending; %zu points, "
              "mean reprojection error %.3f px; %.1f s (the end %.1f s)%s%s\n",
              counts.images_in, model.NumRegisteredImages(), engine_->num_rejected(),
              engine_->PendingImageNames().size(), model.NumPoints3D(),
              model.MeanReprojectionError(), summary_.wall_s, summary_.end_s,
              options_.out.empty() ? "" : ". Output in ", options_.out.c_str());
  if (counts.quarantined + counts.engine_errors + counts.write_errors + counts.skipped_entries >
      0) {
    std::fprintf(options_.output, "problems: %d quarantined images skipped, %d engine errors, %d failed writes, "
                "%d unreadable input entries\n",
                counts.quarantined, counts.engine_errors, counts.write_errors,
                counts.skipped_entries);
  }
  if (checkpointer_) {
    const Checkpointer::Summary& saved = summary_.checkpoint;
    std::fprintf(options_.output, "checkpoint: %.1f ms per image (%.1f %% of the engine's time), %d snapshots "
                "(last %.0f ms, %.1f MB), %.1f MB written; %d images skipped as already in "
                "the model\n",
                counts.images_in > 0 ? counts.checkpoint_ms / counts.images_in : 0.0,
                engine_ms_ > 0 ? 100 * counts.checkpoint_ms / engine_ms_ : 0.0,
                saved.num_snapshots, saved.last_snapshot_ms, saved.last_snapshot_bytes / 1e6,
                saved.bytes / 1e6, counts.in_model);
  }
  if (options_.live && !registration_delays_ms_.empty()) {
    std::fprintf(options_.output, "median delay from arrival to registration: %.0f ms over %zu images\n",
                Median(registration_delays_ms_), registration_delays_ms_.size());
  }
  std::fflush(options_.output);
}

RunLoop::Summary RunState::Go(ImageSource* source) {
  Resume();
  // A resumed run's model so far: measured and published as a whole.
  if (quality_ || view_) engine_->TakeReconstructionChanges();
  if (quality_) quality_->Rebuild(engine_->reconstruction());
  UpdateCoverage(/*now=*/true);
  if (view_) {
    view_->Publish(MakeFullViewUpdate(engine_->reconstruction(), quality_.get(), coverage_.get()));
    coverage_unpublished_ = false;
  }
  ImageSource* input = source;
  if (!options_.out.empty()) {
    // Declared before the prepared source, so that they outlive the prefetch.
    quarantine_ = std::make_unique<Quarantine>(
        std::filesystem::path(options_.out) / "quarantine.tsv", options_.retry_quarantined);
    filtered_ = std::make_unique<QuarantineFilterSource>(source, quarantine_.get(), &in_model_);
    input = filtered_.get();
  }
  {
    PreparedFrameSource prepared(input, engine_->options());
    while (true) {
      RefineWhileIdle(prepared);
      std::optional<PreparedFrame> frame;
      if (const std::optional<std::string> error = ErrorOf([&] { frame = prepared.Next(); })) {
        std::fprintf(stderr, "the image source failed: %s; finishing with what it gave\n",
                     error->c_str());
        source_failed_ = true;
      }
      if (!frame) break;
      ProcessImage(std::move(*frame));
    }
  }
  End();
  if (options_.print) PrintClosingLines();
  return std::move(summary_);
}

}  // namespace

void RunLoop::Options::Check() const {
  if (!(refinement_share > 0 && refinement_share <= 1)) {
    throw std::invalid_argument("refinement_share must be in (0, 1]");
  }
  if (!(refresh_seconds >= 0)) throw std::invalid_argument("refresh_seconds must be >= 0");
  if (!checkpoint.Check()) throw std::invalid_argument("invalid checkpoint options");
  quality.Check();
  if (resume && out.empty()) throw std::invalid_argument("resume needs an output folder");
  if (print && output == nullptr) throw std::invalid_argument("print needs an output");
  if (!(progress_interval_s >= 0)) throw std::invalid_argument("progress_interval_s must be >= 0");
  std::set<std::string> tags;
  for (const std::string& tag : sources) {
    if (tag.empty() || tag.find('/') != std::string::npos || !tags.insert(tag).second) {
      throw std::invalid_argument("sources must be distinct non-empty tags without '/'");
    }
  }
}

RunLoop::RunLoop(Options options, ViewServer* view) : options_(std::move(options)), view_(view) {
  options_.Check();
}

RunLoop::Summary RunLoop::Run(ImageSource* source, Engine* engine, const Hooks& hooks) {
  return RunState(options_, view_, engine, hooks).Go(source);
}

}  // namespace flysfm
