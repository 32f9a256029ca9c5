#include "core/scene/image_result.h"

namespace flysfm {

const std::vector<StageTimes::Stage>& StageTimes::Stages() {
  static const std::vector<Stage> stages = {
      {"decode", &StageTimes::decode},
      {"features", &StageTimes::features},
      {"retrieval", &StageTimes::retrieval},
      {"matching", &StageTimes::matching},
      {"verification", &StageTimes::verification},
      {"lsm", &StageTimes::lsm},
      {"registration", &StageTimes::registration},
      {"triangulation", &StageTimes::triangulation},
      {"ba", &StageTimes::ba},
      {"merge", &StageTimes::merge},
      {"pending", &StageTimes::pending}};
  return stages;
}

void StageTimes::UpdateTotal() {
  total = 0;
  for (const auto& [name, member] : Stages()) total += this->*member;
}

const char* ImageStatusName(ImageStatus status) {
  switch (status) {
    case ImageStatus::kRegistered: return "registered";
    case ImageStatus::kPending: return "pending";
    case ImageStatus::kRejected: return "rejected";
  }
  return "unknown";
}

}  // namespace flysfm
