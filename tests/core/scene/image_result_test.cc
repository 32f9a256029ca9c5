#include "core/scene/image_result.h"

#include <set>
#include <string>
#include <thread>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

TEST_CASE("The total is the sum of the named stages") {
  StageTimes times;
  std::set<std::string> names;
  double value = 1;
  for (const auto& [name, member] : StageTimes::Stages()) {
    names.insert(name);
    times.*member = value;
    value *= 2;
  }
  CHECK(names.size() == StageTimes::Stages().size());
  CHECK(names.count("total") == 0);
  times.UpdateTotal();
  CHECK(times.total == value - 1);
}

TEST_CASE("A scoped stage timer adds its scope's time to its stage") {
  double stage = 5;
  {
    ScopedStageTimer timer(&stage);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  CHECK(stage >= 7);
  CHECK(std::string(ImageStatusName(ImageStatus::kPending)) == "pending");
}

}  // namespace
}  // namespace flysfm
