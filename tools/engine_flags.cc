#include "tools/engine_flags.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <map>
#include <optional>

#include "core/ablation.h"
#include "io/sources/prepared_source.h"
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
  command->add_option("--refresh-seconds", flags->refresh_seconds,
                      "Rewrite the model in --out at most this often while running")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
}

Engine EngineFlags::MakeEngine() const {
  Engine::Options options;
  for (const EngineAblation& ablation : EngineAblations()) {
    const auto it = ablations.find(ablation.flag);
    if (it != ablations.end() && it->second) ablation.apply(&options);
  }
  options.final_global_ba = !no_global_ba;
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

}  // namespace

int RunEngine(ImageSource* source, Engine* engine, const EngineFlags& flags, bool live) {
  RunWriter writer(flags.out);
  const auto start = std::chrono::steady_clock::now();
  auto last_refresh = start;
  const auto seconds_since = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  };
  std::vector<ImageResult> all;
  int num_input = 0;
  // A pending image's later result is timed from its own arrival.
  std::map<std::string, std::chrono::steady_clock::time_point> arrivals;
  std::vector<double> delays_ms;
  const auto report = [&](const std::vector<ImageResult>& results) {
    for (const ImageResult& result : results) {
      std::optional<double> delay_ms;
      const auto arrival = arrivals.find(result.name);
      if (live && arrival != arrivals.end()) {
        delay_ms = 1000 * seconds_since(arrival->second);
        if (result.status == ImageStatus::kRegistered) delays_ms.push_back(*delay_ms);
      }
      PrintLine(num_input, result, delay_ms);
      writer.Log(result);
      all.push_back(result);
    }
  };
  // The next image is decoded and its features extracted on the second core
  // while the engine works on this one.
  PreparedFrameSource prepared(source, engine->options());
  while (std::optional<PreparedFrame> frame = prepared.Next()) {
    ++num_input;
    arrivals[frame->frame.name] = frame->frame.arrival;
    report(engine->AddImage(std::move(*frame)));
    if (seconds_since(last_refresh) >= flags.refresh_seconds) {
      writer.WriteModel(engine->reconstruction());
      writer.WriteSummary(engine->reconstruction(), all, num_input,
                          engine->PendingImageNames(), seconds_since(start));
      last_refresh = std::chrono::steady_clock::now();
    }
  }
  report(engine->Finish());
  writer.WriteModel(engine->reconstruction());
  writer.WriteSummary(engine->reconstruction(), all, num_input,
                      engine->PendingImageNames(), seconds_since(start));
  const Reconstruction& model = engine->reconstruction();
  std::printf("done: %d images in, %zu registered, %d rejected, %zu pending; %zu points, "
              "mean reprojection error %.3f px; %.1f s. Output in %s\n",
              num_input, model.NumRegisteredImages(), engine->num_rejected(),
              engine->PendingImageNames().size(), model.NumPoints3D(),
              model.MeanReprojectionError(), seconds_since(start), flags.out.c_str());
  if (live && !delays_ms.empty()) {
    std::nth_element(delays_ms.begin(), delays_ms.begin() + delays_ms.size() / 2,
                     delays_ms.end());
    std::printf("median delay from arrival to registration: %.0f ms over %zu images\n",
                delays_ms[delays_ms.size() / 2], delays_ms.size());
  }
  return 0;
}

}  // namespace flysfm
