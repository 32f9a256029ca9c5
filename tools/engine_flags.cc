#include "tools/engine_flags.h"

#include <cstdio>
#include <optional>

#include "core/ablation.h"
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
                    "Give the images in OUT/quarantine.tsv (the engine crashed or threw "
                    "on them) another try");
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
  command->add_flag("--no-coverage", flags->no_coverage,
                    "Build no coverage surface and suggest no viewpoints (summary.json's "
                    "\"coverage\", surface.ply, the view's surface and ghost cameras)");
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

int RunFromFlags(ImageSource* source, Engine* engine, const EngineFlags& flags,
                 const CommandRun& run) {
  RunLoop::Options options;
  options.between_images = run.between_images;
  options.refinement_share = flags.refinement_share;
  options.out = flags.out;
  options.refresh_seconds = flags.refresh_seconds;
  options.coverage = !flags.no_coverage;
  options.resume = flags.resume;
  options.retry_quarantined = flags.retry_quarantined;
  options.live = run.live;
  options.skipped_entries = run.skipped_entries;
  options.sources = run.sources;
  const std::unique_ptr<ViewServer> view = StartView(flags.view);
  const RunLoop::Summary summary = RunLoop(options, view.get()).Run(source, engine, run.hooks);
  if (view) {
    view->Finish();
    if (run.keep_view) {
      std::printf("view: the run is over; still serving %s until Ctrl-C\n", view->Url().c_str());
      std::fflush(stdout);
      WaitForInterrupt();
    }
  }
  return summary.exit_code;
}

}  // namespace flysfm
