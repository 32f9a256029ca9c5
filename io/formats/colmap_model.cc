#include "io/formats/colmap_model.h"

#include <cstdint>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "io/formats/atomic_file.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

// COLMAP writes "-1" in text and the all-ones uint64 in binary for "no 3D
// point"; both map to kInvalidPoint3DId.
constexpr std::uint64_t kColmapInvalidPoint3D = std::numeric_limits<std::uint64_t>::max();

template <typename T>
void WriteBinary(std::ostream& out, T value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

template <typename T>
T ReadBinary(std::istream& in, const fs::path& path) {
  T value;
  in.read(reinterpret_cast<char*>(&value), sizeof(T));
  if (!in) throw std::runtime_error(path.string() + ": truncated file");
  return value;
}

// A count read from a corrupt file must not turn into a huge allocation.
std::uint64_t ReadCount(std::istream& in, const fs::path& path) {
  constexpr std::uint64_t kMaxCount = std::uint64_t(1) << 28;
  const auto count = ReadBinary<std::uint64_t>(in, path);
  if (count > kMaxCount) {
    throw std::runtime_error(path.string() + ": implausible count " +
                             std::to_string(count) + " (corrupt file?)");
  }
  return count;
}

std::ifstream OpenForReading(const fs::path& path, bool binary) {
  std::ifstream in(path, binary ? std::ios::binary : std::ios::in);
  if (!in) throw std::runtime_error("cannot open " + path.string());
  return in;
}

// Adds a point's track, validating what came from the file first so that a
// malformed model is an error, not a broken invariant.
void AddPointFromFile(Reconstruction* reconstruction, point3D_t id,
                      const Eigen::Vector3d& xyz,
                      const std::array<std::uint8_t, 3>& color, double error,
                      const std::vector<TrackElement>& track,
                      const std::string& where) {
  if (reconstruction->ExistsPoint3D(id)) {
    throw std::runtime_error(where + ": duplicate point id " + std::to_string(id));
  }
  for (std::size_t i = 0; i < track.size(); ++i) {
    const TrackElement& element = track[i];
    if (!reconstruction->ExistsImage(element.image_id) ||
        !reconstruction->image(element.image_id).IsRegistered() ||
        element.point2D_idx >= reconstruction->image(element.image_id).points2D.size()) {
      throw std::runtime_error(where + ": track of point " + std::to_string(id) +
                               " names a missing image or keypoint");
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (track[j] == element) {
        throw std::runtime_error(where + ": point " + std::to_string(id) +
                                 " observes one keypoint twice");
      }
    }
    if (reconstruction->image(element.image_id).points2D[element.point2D_idx].HasPoint3D()) {
      throw std::runtime_error(where + ": a keypoint observes two points");
    }
  }
  reconstruction->AddPoint3D(xyz, track, color, id);
  reconstruction->point3D(id).error = error;
}

// The point ids listed in images.txt/.bin must agree with the tracks.
void CheckObservationsAgree(
    const Reconstruction& reconstruction,
    const std::map<image_t, std::vector<point3D_t>>& listed, const std::string& where) {
  for (const auto& [image_id, ids] : listed) {
    const Image& image = reconstruction.image(image_id);
    for (std::size_t i = 0; i < ids.size(); ++i) {
      if (ids[i] != image.points2D[i].point3D_id) {
        throw std::runtime_error(where + ": image " + image.name +
                                 " lists observations that the tracks lack");
      }
    }
  }
}

// We place the centre of the top-left pixel at (0, 0), as OpenCV, LSM and the
// TUM calibration do; COLMAP places it at (0.5, 0.5). Keypoints and the
// principal point shift together, so reprojection errors are unchanged.
constexpr double kColmapPixelShift = 0.5;

Camera ToColmapConvention(Camera camera, double shift = kColmapPixelShift) {
  camera.params[camera.NumFocalParams()] += shift;
  camera.params[camera.NumFocalParams() + 1] += shift;
  return camera;
}

Camera FromColmapConvention(const Camera& camera) {
  return ToColmapConvention(camera, -kColmapPixelShift);
}

Camera CameraFromModelId(int model_id, int width, int height, const fs::path& path) {
  Camera camera;
  camera.model_id = static_cast<CameraModelId>(model_id);
  try {
    CameraModelName(camera.model_id);
  } catch (const std::logic_error&) {
    throw std::runtime_error(path.string() + ": unsupported camera model id " +
                             std::to_string(model_id));
  }
  camera.width = width;
  camera.height = height;
  return camera;
}

}  // namespace

void WriteColmapModel(const Reconstruction& reconstruction, const fs::path& dir) {
  WriteColmapText(reconstruction, dir);
  WriteColmapBinary(reconstruction, dir);
}

void WriteColmapText(const Reconstruction& reconstruction, const fs::path& dir) {
  fs::create_directories(dir);
  constexpr int kPrecision = std::numeric_limits<double>::max_digits10;
  WriteFileAtomically(dir / "cameras.txt", [&](std::ostream& out) {
    out << "# Camera list with one line of data per camera:\n"
           "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
        << "# Number of cameras: " << reconstruction.cameras().size() << "\n"
        << std::setprecision(kPrecision);
    for (const auto& [id, our_camera] : reconstruction.cameras()) {
      const Camera camera = ToColmapConvention(our_camera);
      out << id << ' ' << camera.ModelName() << ' ' << camera.width << ' '
          << camera.height;
      for (const double p : camera.params) out << ' ' << p;
      out << '\n';
    }
  });
  WriteFileAtomically(dir / "images.txt", [&](std::ostream& out) {
    out << "# Image list with two lines of data per image:\n"
           "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
           "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
        << "# Number of images: " << reconstruction.NumRegisteredImages()
        << ", mean observations per image: "
        << (reconstruction.NumRegisteredImages()
                ? double(reconstruction.NumObservations()) /
                      reconstruction.NumRegisteredImages()
                : 0.0)
        << "\n"
        << std::setprecision(kPrecision);
    for (const auto& [id, image] : reconstruction.images()) {
      if (!image.IsRegistered()) continue;
      const Rigid3d& pose = *image.cam_from_world;
      out << id << ' ' << pose.rotation.w() << ' ' << pose.rotation.x() << ' '
          << pose.rotation.y() << ' ' << pose.rotation.z() << ' '
          << pose.translation.x() << ' ' << pose.translation.y() << ' '
          << pose.translation.z() << ' ' << image.camera_id << ' ' << image.name
          << '\n';
      for (std::size_t i = 0; i < image.points2D.size(); ++i) {
        const Point2D& p = image.points2D[i];
        out << (i ? " " : "") << p.xy.x() + kColmapPixelShift << ' '
            << p.xy.y() + kColmapPixelShift << ' ';
        if (p.HasPoint3D()) {
          out << p.point3D_id;
        } else {
          out << -1;
        }
      }
      out << '\n';
    }
  });
  WriteFileAtomically(dir / "points3D.txt", [&](std::ostream& out) {
    out << "# 3D point list with one line of data per point:\n"
           "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, "
           "POINT2D_IDX)\n"
        << "# Number of points: " << reconstruction.NumPoints3D()
        << ", mean track length: " << reconstruction.MeanTrackLength() << "\n"
        << std::setprecision(kPrecision);
    for (const auto& [id, point] : reconstruction.points3D()) {
      out << id << ' ' << point.xyz.x() << ' ' << point.xyz.y() << ' '
          << point.xyz.z() << ' ' << int(point.color[0]) << ' '
          << int(point.color[1]) << ' ' << int(point.color[2]) << ' '
          << point.error;
      for (const TrackElement& e : point.track) {
        out << ' ' << e.image_id << ' ' << e.point2D_idx;
      }
      out << '\n';
    }
  });
}

void WriteColmapBinary(const Reconstruction& reconstruction, const fs::path& dir) {
  fs::create_directories(dir);
  WriteFileAtomically(
      dir / "cameras.bin",
      [&](std::ostream& out) {
        WriteBinary<std::uint64_t>(out, reconstruction.cameras().size());
        for (const auto& [id, our_camera] : reconstruction.cameras()) {
          const Camera camera = ToColmapConvention(our_camera);
          WriteBinary<std::uint32_t>(out, id);
          WriteBinary<std::int32_t>(out, static_cast<int>(camera.model_id));
          WriteBinary<std::uint64_t>(out, camera.width);
          WriteBinary<std::uint64_t>(out, camera.height);
          for (const double p : camera.params) WriteBinary<double>(out, p);
        }
      },
      /*binary=*/true);
  WriteFileAtomically(
      dir / "images.bin",
      [&](std::ostream& out) {
        WriteBinary<std::uint64_t>(out, reconstruction.NumRegisteredImages());
        for (const auto& [id, image] : reconstruction.images()) {
          if (!image.IsRegistered()) continue;
          const Rigid3d& pose = *image.cam_from_world;
          WriteBinary<std::uint32_t>(out, id);
          for (const double v : {pose.rotation.w(), pose.rotation.x(),
                                 pose.rotation.y(), pose.rotation.z(),
                                 pose.translation.x(), pose.translation.y(),
                                 pose.translation.z()}) {
            WriteBinary<double>(out, v);
          }
          WriteBinary<std::uint32_t>(out, image.camera_id);
          out.write(image.name.c_str(), image.name.size() + 1);
          WriteBinary<std::uint64_t>(out, image.points2D.size());
          for (const Point2D& p : image.points2D) {
            WriteBinary<double>(out, p.xy.x() + kColmapPixelShift);
            WriteBinary<double>(out, p.xy.y() + kColmapPixelShift);
            WriteBinary<std::uint64_t>(
                out, p.HasPoint3D() ? p.point3D_id : kColmapInvalidPoint3D);
          }
        }
      },
      /*binary=*/true);
  WriteFileAtomically(
      dir / "points3D.bin",
      [&](std::ostream& out) {
        WriteBinary<std::uint64_t>(out, reconstruction.NumPoints3D());
        for (const auto& [id, point] : reconstruction.points3D()) {
          WriteBinary<std::uint64_t>(out, id);
          for (int i = 0; i < 3; ++i) WriteBinary<double>(out, point.xyz[i]);
          for (int i = 0; i < 3; ++i) WriteBinary<std::uint8_t>(out, point.color[i]);
          WriteBinary<double>(out, point.error);
          WriteBinary<std::uint64_t>(out, point.track.size());
          for (const TrackElement& e : point.track) {
            WriteBinary<std::uint32_t>(out, e.image_id);
            WriteBinary<std::uint32_t>(out, e.point2D_idx);
          }
        }
      },
      /*binary=*/true);
}

Reconstruction ReadColmapModel(const fs::path& dir) {
  return fs::exists(dir / "cameras.bin") ? ReadColmapBinary(dir)
                                         : ReadColmapText(dir);
}

Reconstruction ReadColmapText(const fs::path& dir) {
  Reconstruction reconstruction;
  // Yields the data lines of a file with their line numbers.
  const auto for_each_line = [](const fs::path& path, const auto& handle) {
    std::ifstream in = OpenForReading(path, false);
    std::string line;
    for (int number = 1; std::getline(in, line); ++number) {
      if (line.empty() || line[0] == '#') continue;
      handle(line, path.string() + ":" + std::to_string(number), in, number);
    }
  };
  for_each_line(dir / "cameras.txt", [&](const std::string& line,
                                         const std::string& where, auto&, int&) {
    std::istringstream fields(line);
    camera_t id;
    std::string model;
    int width, height;
    if (!(fields >> id >> model >> width >> height)) {
      throw std::runtime_error(where + ": malformed camera line");
    }
    Camera camera;
    try {
      camera = Camera::FromString(
          model + " " + line.substr(static_cast<std::size_t>(fields.tellg())),
          width, height);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(where + ": " + e.what());
    }
    reconstruction.AddCamera(FromColmapConvention(camera), id);
  });
  std::map<image_t, std::vector<point3D_t>> listed;
  for_each_line(dir / "images.txt", [&](const std::string& line,
                                        const std::string& where,
                                        std::istream& in, int& number) {
    std::istringstream fields(line);
    image_t id;
    double qw, qx, qy, qz, tx, ty, tz;
    camera_t camera_id;
    std::string name;
    // The name is the rest of the line: file names may hold spaces.
    if (!(fields >> id >> qw >> qx >> qy >> qz >> tx >> ty >> tz >> camera_id) ||
        !std::getline(fields >> std::ws, name) || name.empty()) {
      throw std::runtime_error(where + ": malformed image line");
    }
    name.erase(name.find_last_not_of(" \r") + 1);
    if (!reconstruction.ExistsCamera(camera_id)) {
      throw std::runtime_error(where + ": unknown camera " + std::to_string(camera_id));
    }
    std::string points_line;
    std::getline(in, points_line);
    ++number;
    std::istringstream points(points_line);
    std::vector<Eigen::Vector2d> keypoints;
    std::vector<point3D_t>& ids = listed[id];
    double x, y;
    long long point3D_id;
    while (points >> x >> y >> point3D_id) {
      keypoints.emplace_back(x - kColmapPixelShift, y - kColmapPixelShift);
      ids.push_back(point3D_id < 0 ? kInvalidPoint3DId : point3D_t(point3D_id));
    }
    if (!points.eof()) throw std::runtime_error(where + ": malformed keypoint list");
    reconstruction.AddImage(name, camera_id, keypoints, id);
    reconstruction.RegisterImage(
        id, Rigid3d(Eigen::Quaterniond(qw, qx, qy, qz), Eigen::Vector3d(tx, ty, tz)));
  });
  for_each_line(dir / "points3D.txt", [&](const std::string& line,
                                          const std::string& where, auto&, int&) {
    std::istringstream fields(line);
    point3D_t id;
    Eigen::Vector3d xyz;
    int r, g, b;
    double error;
    if (!(fields >> id >> xyz.x() >> xyz.y() >> xyz.z() >> r >> g >> b >> error)) {
      throw std::runtime_error(where + ": malformed point line");
    }
    std::vector<TrackElement> track;
    TrackElement element;
    while (fields >> element.image_id >> element.point2D_idx) track.push_back(element);
    if (!fields.eof()) throw std::runtime_error(where + ": malformed track");
    AddPointFromFile(&reconstruction, id, xyz,
                     {std::uint8_t(r), std::uint8_t(g), std::uint8_t(b)}, error,
                     track, where);
  });
  CheckObservationsAgree(reconstruction, listed, (dir / "images.txt").string());
  return reconstruction;
}

Reconstruction ReadColmapBinary(const fs::path& dir) {
  Reconstruction reconstruction;
  {
    const fs::path path = dir / "cameras.bin";
    std::ifstream in = OpenForReading(path, true);
    const auto count = ReadCount(in, path);
    for (std::uint64_t i = 0; i < count; ++i) {
      const auto id = ReadBinary<std::uint32_t>(in, path);
      const auto model_id = ReadBinary<std::int32_t>(in, path);
      const auto width = ReadBinary<std::uint64_t>(in, path);
      const auto height = ReadBinary<std::uint64_t>(in, path);
      Camera camera = CameraFromModelId(model_id, int(width), int(height), path);
      camera.params.resize(camera.NumParams());
      for (double& p : camera.params) p = ReadBinary<double>(in, path);
      if (!camera.IsValid()) {
        throw std::runtime_error(path.string() + ": invalid camera " + std::to_string(id));
      }
      reconstruction.AddCamera(FromColmapConvention(camera), id);
    }
  }
  std::map<image_t, std::vector<point3D_t>> listed;
  {
    const fs::path path = dir / "images.bin";
    std::ifstream in = OpenForReading(path, true);
    const auto count = ReadCount(in, path);
    for (std::uint64_t i = 0; i < count; ++i) {
      const auto id = ReadBinary<std::uint32_t>(in, path);
      double v[7];
      for (double& value : v) value = ReadBinary<double>(in, path);
      const auto camera_id = ReadBinary<std::uint32_t>(in, path);
      std::string name;
      std::getline(in, name, '\0');
      if (!in || !reconstruction.ExistsCamera(camera_id)) {
        throw std::runtime_error(path.string() + ": malformed image record " +
                                 std::to_string(i));
      }
      const auto num_points = ReadCount(in, path);
      std::vector<Eigen::Vector2d> keypoints(num_points);
      std::vector<point3D_t>& ids = listed[id];
      for (auto& keypoint : keypoints) {
        keypoint.x() = ReadBinary<double>(in, path) - kColmapPixelShift;
        keypoint.y() = ReadBinary<double>(in, path) - kColmapPixelShift;
        const auto point3D_id = ReadBinary<std::uint64_t>(in, path);
        ids.push_back(point3D_id == kColmapInvalidPoint3D ? kInvalidPoint3DId
                                                          : point3D_id);
      }
      reconstruction.AddImage(name, camera_id, keypoints, id);
      reconstruction.RegisterImage(
          id, Rigid3d(Eigen::Quaterniond(v[0], v[1], v[2], v[3]),
                      Eigen::Vector3d(v[4], v[5], v[6])));
    }
  }
  {
    const fs::path path = dir / "points3D.bin";
    std::ifstream in = OpenForReading(path, true);
    const auto count = ReadCount(in, path);
    for (std::uint64_t i = 0; i < count; ++i) {
      const auto id = ReadBinary<std::uint64_t>(in, path);
      Eigen::Vector3d xyz;
      for (int k = 0; k < 3; ++k) xyz[k] = ReadBinary<double>(in, path);
      std::array<std::uint8_t, 3> color;
      for (auto& c : color) c = ReadBinary<std::uint8_t>(in, path);
      const double error = ReadBinary<double>(in, path);
      const auto length = ReadCount(in, path);
      std::vector<TrackElement> track(length);
      for (TrackElement& e : track) {
        e.image_id = ReadBinary<std::uint32_t>(in, path);
        e.point2D_idx = ReadBinary<std::uint32_t>(in, path);
      }
      AddPointFromFile(&reconstruction, id, xyz, color, error, track,
                       path.string() + " record " + std::to_string(i));
    }
  }
  CheckObservationsAgree(reconstruction, listed, (dir / "images.bin").string());
  return reconstruction;
}

}  // namespace flysfm
