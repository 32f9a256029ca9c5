#include "core/ablation.h"

namespace flysfm {

const std::vector<EngineAblation>& EngineAblations() {
  static const std::vector<EngineAblation> kAblations = {
      {"no LSM refinement", "--no-lsm-refinement",
       "Ablation: keep raw SIFT positions (no LSM refinement)",
       [](Engine::Options* o) { o->verification.lsm_refinement = false; }},
      {"no LSM densification", "--no-lsm-densification",
       "Ablation: no LSM densification of 2D-3D correspondences",
       [](Engine::Options* o) { o->registration.lsm_densification = false; }},
      {"plain local BA (no weights)", "--no-hierarchical-weights",
       "Ablation: plain local BA of the association tree's images",
       [](Engine::Options* o) { o->hierarchical_weights = false; }},
      {"exhaustive retrieval", "--exhaustive-retrieval",
       "Ablation: exhaustive global-descriptor search, no vocabulary tree",
       [](Engine::Options* o) { o->retrieval.use_tree = false; }},
      {"no track completion or merging", "--no-track-completion",
       "Ablation: new images continue and start tracks, but no track is completed "
       "with other images' matches or merged with another",
       [](Engine::Options* o) { o->triangulation.complete_and_merge_tracks = false; }},
      {"no snooping", "--no-snooping",
       "Ablation: no data snooping, between shots nor in Finish; the model keeps every "
       "observation within the 4 px filter",
       [](Engine::Options* o) { o->outlier_quantile = 0; }},
  };
  return kAblations;
}

}  // namespace flysfm
