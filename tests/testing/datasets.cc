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

}  // namespace

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

}  // namespace flysfm::testing
