#include "tests/testing/datasets.h"

#include <fstream>
#include <sstream>
#include <stdexcept>

#include "io/formats/data_lines.h"

namespace flysfm::testing {
namespace {

std::ifstream Open(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open '" + path + "'");
  return in;
}

// Lines that are neither empty nor '#' comments.
std::vector<std::string> DataLines(const std::string& path) {
  std::ifstream in = Open(path);
  std::vector<std::string> lines;
  ForEachDataLine(in, [&](const std::string& line, int) { lines.push_back(line); });
  return lines;
}

[[noreturn]] void Malformed(const std::string& path, const std::string& line) {
  throw std::runtime_error("malformed line in '" + path + "': " + line);
}

// "PINHOLE fx,fy,cx,cy" with the digits the data files give.
std::string PinholeOption(const Eigen::Matrix3d& K) {
  std::ostringstream option;
  option << "PINHOLE " << K(0, 0) << "," << K(1, 1) << "," << K(0, 2) << "," << K(1, 2);
  return option.str();
}

PhotoSet WithCamera(std::string name, std::vector<Frame> frames, const Eigen::Matrix3d& K) {
  PhotoSet set;
  set.name = std::move(name);
  set.frames = std::move(frames);
  set.camera = PinholeOption(K);
  set.focal_length = (K(0, 0) + K(1, 1)) / 2;
  return set;
}

}  // namespace

std::map<std::string, Eigen::Vector3d> PhotoSet::Centres() const {
  std::map<std::string, Eigen::Vector3d> centres;
  for (const auto& [name, pose] : cam_from_world) centres[name] = ProjectionCenter(pose);
  return centres;
}

StrechaCamera ReadStrechaCamera(const std::string& path) {
  std::ifstream in = Open(path);
  StrechaCamera camera;
  double k1, k2, k3;
  for (int r = 0; r < 3; ++r) in >> camera.K(r, 0) >> camera.K(r, 1) >> camera.K(r, 2);
  in >> k1 >> k2 >> k3;
  for (int r = 0; r < 3; ++r) in >> camera.R(r, 0) >> camera.R(r, 1) >> camera.R(r, 2);
  in >> camera.centre.x() >> camera.centre.y() >> camera.centre.z() >> camera.width >>
      camera.height;
  if (!in) throw std::runtime_error("malformed Strecha camera file '" + path + "'");
  return camera;
}

std::vector<MiddleburyCamera> ReadMiddleburyCameras(const std::string& par_txt) {
  std::vector<std::string> lines = DataLines(par_txt);
  // The first line is the number of cameras.
  if (lines.empty()) throw std::runtime_error("empty Middlebury file '" + par_txt + "'");
  std::vector<MiddleburyCamera> cameras;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    std::istringstream stream(lines[i]);
    MiddleburyCamera camera;
    stream >> camera.name;
    for (int r = 0; r < 3; ++r) stream >> camera.K(r, 0) >> camera.K(r, 1) >> camera.K(r, 2);
    for (int r = 0; r < 3; ++r) stream >> camera.R(r, 0) >> camera.R(r, 1) >> camera.R(r, 2);
    stream >> camera.t.x() >> camera.t.y() >> camera.t.z();
    if (!stream) Malformed(par_txt, lines[i]);
    cameras.push_back(camera);
  }
  return cameras;
}

Eigen::Matrix3d ReadIntrinsicMatrix(const std::string& path) {
  std::ifstream in = Open(path);
  Eigen::Matrix3d K;
  for (int r = 0; r < 3; ++r) in >> K(r, 0) >> K(r, 1) >> K(r, 2);
  if (!in) throw std::runtime_error("malformed intrinsic matrix file '" + path + "'");
  return K;
}

PhotoSet FountainP11(const std::filesystem::path& data) {
  const std::filesystem::path dir = data / "strecha/fountain-P11";
  PhotoSet set = WithCamera("fountain-P11", ListImageFolder(dir / "images"),
                            ReadIntrinsicMatrix((dir / "images/K.txt").string()));
  for (const Frame& frame : set.frames) {
    set.cam_from_world[frame.name] =
        ReadStrechaCamera((dir / "gt_dense_cameras" / (frame.name + ".camera")).string())
            .CamFromWorld();
  }
  return set;
}

PhotoSet SceauxCastle(const std::filesystem::path& data) {
  const std::filesystem::path dir = data / "sceaux_castle/images";
  return WithCamera("sceaux_castle", ListImageFolder(dir),
                    ReadIntrinsicMatrix((dir / "K.txt").string()));
}

PhotoSet TempleRing19(const std::filesystem::path& data) {
  const std::filesystem::path dir = data / "middlebury/templeRing_subset19";
  const std::vector<MiddleburyCamera> cameras =
      ReadMiddleburyCameras((dir / "templeR_par.txt").string());
  if (cameras.empty()) throw std::runtime_error("no cameras in templeR_par.txt");
  PhotoSet set = WithCamera("templeRing_subset19", ListImageFolder(dir), cameras.front().K);
  // The ring's file has all 47 views; the subset keeps 19.
  for (const MiddleburyCamera& camera : cameras) {
    set.cam_from_world[camera.name] = camera.CamFromWorld();
  }
  return set;
}

}  // namespace flysfm::testing
