#include "tools/engine_flags.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <map>
#include <optional>
#include <unordered_set>

#include "core/ablation.h"
#include "io/run/checkpoint.h"
#include "io/sources/prepared_source.h"
#include "io/sources/quarantine.h"
#include "retrieval/retrieval_model.h"

namespace flysfm {

void AddEngineFlags(CLI::App* command, EngineFlags* flags) {
  CLI::Option* out =
      command->add_option("--out", flags->out, "Output folder (model, log, summary)");
  // A command that presets the folder makes it optional.
  if (flags->out.empty()) {
    out->required();
  } else {
    out->capture_default_str();
  }
  command->add_option("--camera", flags->camera,
                      "Known intrinsics shared by all images, \"MODEL p1,p2,...\" in "
                      "COLMAP's parameter order (e.g. \"FULL_OPENCV 517.3,516.5,318.6,"
                      "255.3,0.2624,-0.9531,-0.0054,0.0026,1.1633,0,0,0\"); held fixed. "
                      "Default: unknown, SIMPLE_RADIAL guessed and refined");
  command->add_option("--retrieval-model", flags->retrieval_model,
                      "Retrieval model from `flysfm train-retrieval`. Default: "
                      "bootstrapped from the session's own images");
  for (const EngineAblation& ablation : EngineAblations()) {
    command->add_flag(ablation.flag, flags->ablations[ablation.flag], ablation.help);
  }
  command->add_flag("--no-global-ba", flags->no_global_ba,
                    "Skip the global bundle adjustment at the end");
  command->add_flag("--no-refinement", flags->no_refinement,
                    "Do not refine the model between images (more pairs matched, tracks "
                    "completed and merged, global BAs); the model is then what each image's "
                    "registration left, and the global BA at the end");
  command->add_option("--refinement-share", flags->refinement_share,
                      "Share of the engine's core that refinement may take while no image "
                      "waits: after a slice of t seconds it rests t (1/share - 1) seconds")
      ->check(CLI::Range(0.01, 1.0))
      ->capture_default_str();
  command->add_flag("--retry-quarantined", flags->retry_quarantined,
                    "Give the images in OUT/quarantine.tsv (a previous run died or the "
                    "engine failed on them) another try");
  command->add_option("--max-megapixels", flags->max_megapixels,
                      "Reject an image whose header claims more pixels, before decoding it "
                      "(a corrupt or hostile file may claim 60000 x 60000)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--lsm-window-budget", flags->lsm_window_budget_mb,
                      "Megabytes of older images' pixels kept for LSM (windows around their "
                      "points); past it the least recently used image's are dropped and its "
                      "later pairs stay unrefined")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--refresh-seconds", flags->refresh_seconds,
                      "Rewrite the model in --out at most this often while running")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  AddViewFlags(command, &flags->view);
}

Engine EngineFlags::MakeEngine() const {
  Engine::Options options;
  for (const EngineAblation& ablation : EngineAblations()) {
    const auto it = ablations.find(ablation.flag);
    if (it != ablations.end() && it->second) ablation.apply(&options);
  }
  options.final_global_ba = !no_global_ba;
  options.refinement.enabled = !no_refinement;
  options.decode.max_image_pixels = max_megapixels * 1e6;
  options.lsm_images.window_budget_megabytes = lsm_window_budget_mb;
  std::optional<Camera> known_camera;
  if (!camera.empty()) known_camera = Camera::FromString(camera, 0, 0);
  std::shared_ptr<const RetrievalModel> model;
  if (!retrieval_model.empty()) {
    model = std::make_shared<const RetrievalModel>(RetrievalModel::Load(retrieval_model));
  }
  return Engine(options, known_camera, model);
}

namespace {

void PrintLine(int index, const ImageResult& result, std::optional<double> delay_ms) {
  char delay[48] = "";
  if (delay_ms) std::snprintf(delay, sizeof(delay), "  delay %6.0f ms", *delay_ms);
  std::printf("[%4d] %-32s %-10s %6d pts %+5d new %7.0f ms  model %d img / %d pts%s%s%s\n",
              index, result.name.c_str(), ImageStatusName(result.status),
              result.num_observations, result.num_new_points, result.times.total,
              result.model_images, result.model_points, delay,
              result.reason.empty() ? "" : "  ", result.reason.c_str());
  std::fflush(stdout);
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

}  // namespace

int RunEngine(ImageSource* source, Engine* engine, const EngineFlags& flags,
              const RunEngineOptions& options) {
  RunWriter writer(flags.out);
  const auto start = std::chrono::steady_clock::now();
  Checkpointer checkpointer(std::filesystem::path(flags.out) / "state", Checkpointer::Options());
  std::unordered_set<std::string> in_model;
  if (flags.resume && checkpointer.Exists()) {
    try {
      checkpointer.Restore(engine);
    } catch (const std::exception& e) {
      throw std::runtime_error("cannot resume from " + checkpointer.dir().string() + ": " +
                               e.what() + "; move that folder away to start the model over");
    }
    for (const auto& [image_id, image] : engine->reconstruction().images()) {
      in_model.insert(image.name);
    }
    std::printf("resumed: %zu images (%zu registered, %zu points) from %s in %.1f s\n",
                in_model.size(), engine->reconstruction().NumRegisteredImages(),
                engine->reconstruction().NumPoints3D(), checkpointer.dir().c_str(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    std::fflush(stdout);
  } else {
    checkpointer.Clear();
  }
  // Started before the first image, so that a port in use fails the run at
  // once rather than after it.
  const std::unique_ptr<ViewServer> view = StartView(flags.view);
  std::vector<ViewLine> view_lines;
  // Each step's changes to the model, as the page draws them (docs/view.md).
  const auto publish_view = [&] {
    if (!view) return;
    view->Publish(MakeViewUpdate(engine->reconstruction(), engine->TakeReconstructionChanges(),
                                 std::move(view_lines)));
    view_lines.clear();
  };
  if (view) {
    // A resumed run's model so far, as one update.
    engine->TakeReconstructionChanges();
    view->Publish(MakeFullViewUpdate(engine->reconstruction()));
  }
  auto last_refresh = start;
  const auto seconds_since = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  };
  std::vector<ImageResult> all;
  RunCounts counts;
  counts.skipped_entries = options.skipped_entries;
  counts.resumed_images = int(in_model.size());
  double engine_ms = 0;
  // A failed checkpoint write (a full disk) is counted like any failed
  // output; the next one writes what is still missing.
  const auto checkpoint = [&](double call_ms, bool final) {
    engine_ms += call_ms;
    try {
      checkpointer.Update(*engine, call_ms, final);
    } catch (const std::exception& e) {
      ++counts.write_errors;
      std::fprintf(stderr, "cannot write the checkpoint: %s\n", e.what());
    }
    const Checkpointer::Summary& summary = checkpointer.summary();
    counts.checkpoint_ms = summary.records_ms + summary.snapshots_ms;
  };
  // A pending image's later result is timed from its own arrival.
  std::map<std::string, std::chrono::steady_clock::time_point> arrivals;
  std::vector<double> delays_ms;
  const auto report = [&](const std::vector<ImageResult>& results) {
    for (const ImageResult& result : results) {
      std::optional<double> delay_ms;
      const auto arrival = arrivals.find(result.name);
      if (options.live && arrival != arrivals.end()) {
        delay_ms = 1000 * seconds_since(arrival->second);
        if (result.status == ImageStatus::kRegistered) delays_ms.push_back(*delay_ms);
      }
      PrintLine(counts.images_in, result, delay_ms);
      if (view) view_lines.push_back(MakeViewLine(result, delay_ms));
      writer.Log(result);
      all.push_back(result);
    }
  };
  // Declared before the prepared source, so that they outlive the prefetch.
  Quarantine quarantine(std::filesystem::path(flags.out) / "quarantine.tsv",
                        flags.retry_quarantined);
  QuarantineFilterSource filtered(source, &quarantine, &in_model);
  // A failed write (a full disk, a folder made read-only) loses no image:
  // the engine's model is whole, and the next write tries again.
  const auto write_outputs = [&](bool final) {
    counts.quarantined = filtered.num_skipped();
    counts.in_model = filtered.num_in_model();
    counts.refinement = engine->refinement_totals();
    try {
      if (!writer.MayReplaceOutputs(engine->reconstruction(), final)) return true;
      writer.WriteModel(engine->reconstruction());
      writer.WriteSummary(engine->reconstruction(), all, counts,
                          engine->PendingImageNames(), seconds_since(start));
      return true;
    } catch (const std::exception& e) {
      ++counts.write_errors;
      std::fprintf(stderr, "cannot write the outputs in %s: %s\n", flags.out.c_str(), e.what());
      return false;
    }
  };
  std::function<std::vector<ImageResult>(Engine*, PreparedFrame)> add_image =
      options.add_image;
  if (!add_image) {
    add_image = [](Engine* engine, PreparedFrame frame) {
      return engine->AddImage(std::move(frame));
    };
  }
  bool source_failed = false;
  bool refinement_failed = false;
  {
    // The next image is decoded and its features extracted on the second
    // core while the engine works on this one.
    PreparedFrameSource prepared(&filtered, engine->options());
    const auto refine_while_idle = [&] {
      if (refinement_failed) return;
      const std::optional<std::string> error = ErrorOf([&] {
        RefineUntilNextFrame(engine, prepared, flags.refinement_share,
                             [&](Engine::RefinementSlice* slice) {
                               report(slice->registered);
                               publish_view();
                               if (seconds_since(last_refresh) >= flags.refresh_seconds) {
                                 write_outputs(/*final=*/false);
                                 last_refresh = std::chrono::steady_clock::now();
                               }
                             });
      });
      if (error) {
        ++counts.engine_errors;
        refinement_failed = true;
        std::fprintf(stderr, "engine error while refining: %s; no more refinement in this "
                     "run\n", error->c_str());
      }
    };
    while (true) {
      if (options.refine_between_images) refine_while_idle();
      std::optional<PreparedFrame> frame;
      if (const std::optional<std::string> error = ErrorOf([&] { frame = prepared.Next(); })) {
        std::fprintf(stderr, "the image source failed: %s; finishing with what it gave\n",
                     error->c_str());
        source_failed = true;
      }
      if (!frame) break;
      ++counts.images_in;
      const std::string name = frame->frame.name;
      arrivals[name] = frame->frame.arrival;
      if (view) view->SetLatestShot(frame->image);
      quarantine.BeginEngine(name);
      std::vector<ImageResult> results;
      const auto call_start = std::chrono::steady_clock::now();
      const std::optional<std::string> error =
          ErrorOf([&] { results = add_image(engine, std::move(*frame)); });
      const double call_ms = 1000 * seconds_since(call_start);
      if (!error) {
        quarantine.Done(name);
      } else {
        ++counts.engine_errors;
        quarantine.Fail(name, "engine error: " + *error);
        std::fprintf(stderr, "engine error on %s: %s; the image is quarantined\n", name.c_str(),
                     error->c_str());
        ImageResult failed;
        failed.name = name;
        failed.status = ImageStatus::kRejected;
        failed.reason = "engine error (quarantined): " + *error;
        results.push_back(failed);
      }
      report(results);
      checkpoint(call_ms, /*final=*/false);
      publish_view();
      if (seconds_since(last_refresh) >= flags.refresh_seconds) {
        write_outputs(/*final=*/false);
        last_refresh = std::chrono::steady_clock::now();
      }
    }
  }
  const auto finish_start = std::chrono::steady_clock::now();
  if (options.refine_between_images && !refinement_failed) {
    // The source is done: what refinement has left, at once (a second
    // Ctrl-C in live quits; the checkpoint holds every image).
    const std::optional<std::string> error =
        ErrorOf([&] { report(engine->RefineToEnd()); });
    if (error) {
      ++counts.engine_errors;
      std::fprintf(stderr, "engine error while refining: %s\n", error->c_str());
    }
  }
  if (const std::optional<std::string> error = ErrorOf([&] { report(engine->Finish()); })) {
    ++counts.engine_errors;
    std::fprintf(stderr, "engine error while finishing: %s; the model is written as it is\n",
                 error->c_str());
  }
  checkpoint(1000 * seconds_since(finish_start), /*final=*/true);
  publish_view();
  const bool written = write_outputs(/*final=*/true);
  const Reconstruction& model = engine->reconstruction();
  std::printf("done: %d images in, %zu registered, %d rejected, %zu pending; %zu points, "
              "mean reprojection error %.3f px; %.1f s. Output in %s\n",
              counts.images_in, model.NumRegisteredImages(), engine->num_rejected(),
              engine->PendingImageNames().size(), model.NumPoints3D(),
              model.MeanReprojectionError(), seconds_since(start), flags.out.c_str());
  if (counts.quarantined + counts.engine_errors + counts.write_errors + counts.skipped_entries >
      0) {
    std::printf("problems: %d quarantined images skipped, %d engine errors, %d failed writes, "
                "%d unreadable input entries\n",
                counts.quarantined, counts.engine_errors, counts.write_errors,
                counts.skipped_entries);
  }
  const Checkpointer::Summary& saved = checkpointer.summary();
  std::printf("checkpoint: %.1f ms per image (%.1f %% of the engine's time), %d snapshots "
              "(last %.0f ms, %.1f MB), %.1f MB written; %d images skipped as already in the "
              "model\n",
              counts.images_in > 0 ? counts.checkpoint_ms / counts.images_in : 0.0,
              engine_ms > 0 ? 100 * counts.checkpoint_ms / engine_ms : 0.0, saved.num_snapshots,
              saved.last_snapshot_ms, saved.last_snapshot_bytes / 1e6, saved.bytes / 1e6,
              counts.in_model);
  if (options.live && !delays_ms.empty()) {
    std::nth_element(delays_ms.begin(), delays_ms.begin() + delays_ms.size() / 2,
                     delays_ms.end());
    std::printf("median delay from arrival to registration: %.0f ms over %zu images\n",
                delays_ms[delays_ms.size() / 2], delays_ms.size());
  }
  if (view) {
    view->Finish();
    if (options.keep_view) {
      std::printf("view: the run is over; still serving %s until Ctrl-C\n", view->Url().c_str());
      std::fflush(stdout);
      WaitForInterrupt();
    }
  }
  return written && !source_failed ? 0 : 1;
}

}  // namespace flysfm
