// The engine's checkpoint: Engine::WriteImageRecord, WriteLsmWindows,
// WriteSnapshot and Restore (docs/engine.md, "Resume").

#include <algorithm>

#include "core/engine.h"
#include "geometry/binary_io.h"
#include "geometry/check.h"
#include "matching/image_decode.h"

namespace flysfm {
namespace {

constexpr char kImageRecordMagic[9] = "FSIMAGE1";
constexpr char kSnapshotMagic[9] = "FSENGINE";
// 4: descriptors as bytes (SiftDescriptors).
constexpr std::uint32_t kCheckpointVersion = 4;

std::string CameraText(const std::optional<Camera>& camera) {
  return camera ? camera->ToString() : std::string("unknown intrinsics");
}

}  // namespace

void Engine::WriteImageRecord(image_t image_id, std::ostream& out) const {
  WriteHeader(out, kImageRecordMagic, kCheckpointVersion);
  WriteString(out, reconstruction_.image(image_id).name);
  const std::filesystem::path& file = image_files_.at(image_id);
  // A restart may run from another folder.
  WriteString(out, file.empty() ? std::string() : std::filesystem::absolute(file).string());
  WriteFeatureSet(out, features_.at(image_id));
  // Pairs are verified when their newer image arrives: the matches with
  // older images are all this image will ever have written for it. Those
  // refinement verifies later are tried again after a restore.
  std::vector<image_t> older;
  for (const image_t other_id : matches_.Neighbours(image_id)) {
    if (other_id < image_id) older.push_back(other_id);
  }
  WriteCount(out, older.size());
  for (const image_t other_id : older) {
    WriteValue(out, other_id);
    WriteVector(out, matches_.Matches(image_id, other_id));
  }
  // And the older images it was tried with, verified or not, which
  // refinement does not try again.
  std::vector<image_t> tried;
  for (const auto& [other_id, other] : reconstruction_.images()) {
    if (other_id >= image_id) break;
    if (refinement_.tried_pairs.count(ImagePairKey(image_id, other_id))) tried.push_back(other_id);
  }
  WriteVector(out, tried);
}

void Engine::WriteSnapshot(std::ostream& out) const {
  WriteHeader(out, kSnapshotMagic, kCheckpointVersion);
  WriteString(out, CameraText(known_camera_));
  reconstruction_.Write(out);
  WriteValue(out, retriever_.model_version());
  retriever_.Write(out);
  pending_.Write(out);
  initializer_.Write(out);
  WriteCount(out, camera_by_identity_.size());
  for (const auto& [key, camera_id] : camera_by_identity_) {
    WriteValue(out, std::get<0>(key));
    WriteValue(out, std::get<1>(key));
    WriteString(out, std::get<2>(key));
    WriteValue(out, camera_id);
  }
  WriteCount(out, self_calibrating_.size());
  for (const auto& [camera_id, calm] : self_calibrating_) {
    WriteValue(out, camera_id);
    WriteValue(out, calm);
  }
  WriteValue(out, std::uint64_t(next_self_calibration_images_));
  WriteValue(out, std::uint8_t(initialized_));
  WriteValue(out, num_rejected_);
  lsm_images_.WriteState(out);
}

void Engine::Restore(std::istream& snapshot, const CheckpointFiles& files) {
  FLYSFM_CHECK(reconstruction_.images().empty());
  ReadHeader(snapshot, kSnapshotMagic, kCheckpointVersion);
  const std::string camera = ReadString(snapshot, "camera");
  if (camera != CameraText(known_camera_)) {
    throw std::runtime_error("the checkpointed run had camera \"" + camera +
                             "\", this one \"" + CameraText(known_camera_) +
                             "\": resume with the same --camera");
  }
  reconstruction_ = Reconstruction::Read(snapshot);
  for (const auto& [image_id, image] : reconstruction_.images()) {
    const std::unique_ptr<std::istream> record = files.record(image_id);
    if (!record) {
      throw std::runtime_error("the checkpoint has no record of image " + image.name);
    }
    ReadHeader(*record, kImageRecordMagic, kCheckpointVersion);
    if (ReadString(*record, "image name") != image.name) {
      throw std::runtime_error("the checkpoint's record of image " + image.name +
                               " names another image");
    }
    image_files_[image_id] = ReadString(*record, "image file");
    FeatureSet& features = features_[image_id] = ReadFeatureSet(*record);
    if (std::size_t(features.size()) > image.points2D.size()) {
      throw std::runtime_error("the checkpoint's record of image " + image.name +
                               " has more features than the model");
    }
    const std::size_t num_pairs = ReadCount(*record, "verified pairs", std::size_t(1) << 24);
    for (std::size_t i = 0; i < num_pairs; ++i) {
      const auto other_id = ReadValue<image_t>(*record, "verified pair");
      std::vector<FeatureMatch> matches =
          ReadVector<FeatureMatch>(*record, "verified matches", std::size_t(1) << 24);
      const auto other = features_.find(other_id);
      if (other_id >= image_id || other == features_.end() ||
          std::any_of(matches.begin(), matches.end(), [&](const FeatureMatch& match) {
            return match.idx1 < 0 || match.idx1 >= features.size() || match.idx2 < 0 ||
                   match.idx2 >= other->second.size();
          })) {
        throw std::runtime_error("the checkpoint's record of image " + image.name +
                                 " has a bad verified pair");
      }
      matches_.SetMatches(image_id, other_id, std::move(matches));
    }
    for (const image_t other_id :
         ReadVector<image_t>(*record, "tried pairs", std::size_t(1) << 24)) {
      if (other_id >= image_id || !features_.count(other_id)) {
        throw std::runtime_error("the checkpoint's record of image " + image.name +
                                 " has a bad tried pair");
      }
      refinement_.tried_pairs.insert(ImagePairKey(image_id, other_id));
    }
  }
  const int model_version = ReadValue<int>(snapshot, "retrieval model version");
  const std::unique_ptr<std::istream> model =
      model_version > 0 ? files.retrieval_model(model_version) : nullptr;
  retriever_.Read(snapshot, model.get(), [this](image_t image_id) -> const FeatureSet& {
    const auto features = features_.find(image_id);
    if (features == features_.end()) {
      throw std::runtime_error("the checkpoint's retrieval names an unknown image");
    }
    return features->second;
  });
  pending_.Read(snapshot);
  initializer_.Read(snapshot);
  const std::size_t num_identities = ReadCount(snapshot, "camera identities", 1 << 20);
  for (std::size_t i = 0; i < num_identities; ++i) {
    const auto width = ReadValue<int>(snapshot, "camera identity");
    const auto height = ReadValue<int>(snapshot, "camera identity");
    std::string identity = ReadString(snapshot, "camera identity");
    const auto camera_id = ReadValue<camera_t>(snapshot, "camera identity");
    if (!reconstruction_.ExistsCamera(camera_id)) {
      throw std::runtime_error("the checkpoint names an unknown camera");
    }
    camera_by_identity_[{width, height, std::move(identity)}] = camera_id;
  }
  const std::size_t num_calibrating = ReadCount(snapshot, "self-calibrating cameras", 1 << 20);
  for (std::size_t i = 0; i < num_calibrating; ++i) {
    const auto camera_id = ReadValue<camera_t>(snapshot, "self-calibrating camera");
    self_calibrating_[camera_id] = ReadValue<int>(snapshot, "self-calibrating camera");
  }
  next_self_calibration_images_ =
      std::size_t(ReadValue<std::uint64_t>(snapshot, "next self-calibration"));
  initialized_ = ReadValue<std::uint8_t>(snapshot, "initialisation") != 0;
  num_rejected_ = ReadValue<int>(snapshot, "rejections");
  for (const image_t image_id : pending_.Images()) {
    if (!reconstruction_.ExistsImage(image_id)) {
      throw std::runtime_error("the checkpoint's pending pool names an unknown image");
    }
  }
  lsm_images_.ReadState(
      snapshot,
      [this](image_t image_id) -> cv::Mat {
        const std::filesystem::path& file = image_files_.at(image_id);
        if (file.empty()) return {};
        // Only the grey is read: the colour as small as decoding allows.
        DecodedImage decoded = DecodeImageFile(file.string(), options_.decode, 1);
        const Camera& camera =
            reconstruction_.camera(reconstruction_.image(image_id).camera_id);
        if (!decoded.ok() || decoded.grey.cols != camera.width ||
            decoded.grey.rows != camera.height) {
          return {};
        }
        return decoded.grey;
      },
      files.windows,
      [this](image_t image_id) {
        std::vector<Eigen::Vector2d> points;
        for (const Point2D& point2D : reconstruction_.image(image_id).points2D) {
          points.push_back(point2D.xy);
        }
        return points;
      });
  // Refinement starts over: the pairs it tried are not checkpointed, and
  // are tried again between the next shots.
  for (const auto& [image_id, image] : reconstruction_.images()) {
    refinement_.to_match.push_back(image_id);
  }
  refinement_.adjust = initialized_;
}

}  // namespace flysfm
