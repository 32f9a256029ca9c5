#include "core/ablation.h"

#include <set>
#include <string>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

// Each switch must change something: an ablation that left the options as
// they were would measure the full pipeline twice under two names. The
// options have no operator==, so the fields the switches own are compared.
auto Fields(const Engine::Options& o) {
  return std::make_tuple(o.verification.lsm_refinement, o.registration.lsm_densification,
                         o.hierarchical_weights, o.retrieval.use_tree,
                         o.triangulation.complete_and_merge_tracks, o.outlier_quantile);
}

TEST_CASE("Each ablation switch changes one component, under its own flag and name") {
  std::set<std::string> names, flags;
  std::set<decltype(Fields(Engine::Options()))> outcomes;
  const auto full = Fields(Engine::Options());
  for (const EngineAblation& ablation : EngineAblations()) {
    INFO(ablation.name);
    Engine::Options options;
    ablation.apply(&options);
    CHECK(options.Check());
    CHECK(Fields(options) != full);
    CHECK(std::string(ablation.flag).rfind("--", 0) == 0);
    names.insert(ablation.name);
    flags.insert(ablation.flag);
    outcomes.insert(Fields(options));
  }
  const std::size_t n = EngineAblations().size();
  CHECK(names.size() == n);
  CHECK(flags.size() == n);
  CHECK(outcomes.size() == n);
}

}  // namespace
}  // namespace flysfm
