#include "io/formats/ply.h"

#include <cstdint>

#include "io/formats/atomic_file.h"

namespace flysfm {

void WritePly(const Reconstruction& reconstruction, const std::filesystem::path& path,
              const std::unordered_map<point3D_t, PointQuality>* quality) {
  WriteFileAtomically(
      path,
      [&](std::ostream& out) {
        out << "ply\nformat binary_little_endian 1.0\n"
            << "element vertex " << reconstruction.NumPoints3D() << "\n"
            << "property double x\nproperty double y\nproperty double z\n"
               "property uchar red\nproperty uchar green\nproperty uchar blue\n";
        if (quality) {
          out << "property int views\nproperty float max_angle_deg\n"
                 "property float error_px\nproperty float sigma\n";
        }
        out << "end_header\n";
        for (const auto& [id, point] : reconstruction.points3D()) {
          out.write(reinterpret_cast<const char*>(point.xyz.data()), 3 * sizeof(double));
          out.write(reinterpret_cast<const char*>(point.color.data()), 3);
          if (!quality) continue;
          std::int32_t views = 0;
          float values[3] = {0, 0, kPlyUndefinedSigma};
          const auto measured = quality->find(id);
          if (measured != quality->end()) {
            views = measured->second.views;
            values[0] = float(measured->second.max_angle_deg);
            values[1] = float(measured->second.error_px);
            if (measured->second.sigma) values[2] = float(*measured->second.sigma);
          }
          // The file is little-endian, as is every machine flysfm builds on
          // (x86-64, arm64).
          out.write(reinterpret_cast<const char*>(&views), sizeof(views));
          out.write(reinterpret_cast<const char*>(values), sizeof(values));
        }
      },
      /*binary=*/true);
}

void WriteSurfacePly(const Coverage& coverage, const std::filesystem::path& path) {
  const std::vector<Coverage::Face>& faces = coverage.faces();
  WriteFileAtomically(
      path,
      [&](std::ostream& out) {
        out << "ply\nformat binary_little_endian 1.0\n"
            << "element vertex " << 3 * faces.size() << "\n"
            << "property float x\nproperty float y\nproperty float z\n"
            << "element face " << faces.size() << "\n"
            << "property list uchar int vertex_indices\n"
               "property uchar red\nproperty uchar green\nproperty uchar blue\n"
               "property int views\nproperty float max_angle_deg\nproperty float gsd\n"
               "property uchar coverage_class\nend_header\n";
        for (const Coverage::Face& face : faces) {
          for (const Eigen::Vector3d& corner : face.corners) {
            const float xyz[3] = {float(corner.x()), float(corner.y()), float(corner.z())};
            out.write(reinterpret_cast<const char*>(xyz), sizeof(xyz));
          }
        }
        for (std::size_t i = 0; i < faces.size(); ++i) {
          const Coverage::Face& face = faces[i];
          const std::uint8_t corners = 3;
          out.write(reinterpret_cast<const char*>(&corners), 1);
          const std::int32_t indices[3] = {std::int32_t(3 * i), std::int32_t(3 * i + 1),
                                           std::int32_t(3 * i + 2)};
          out.write(reinterpret_cast<const char*>(indices), sizeof(indices));
          const std::array<std::uint8_t, 3> colour = FaceClassColour(face.face_class);
          out.write(reinterpret_cast<const char*>(colour.data()), 3);
          const std::int32_t views = face.views;
          out.write(reinterpret_cast<const char*>(&views), sizeof(views));
          const float values[2] = {float(face.max_angle_deg), float(face.gsd)};
          out.write(reinterpret_cast<const char*>(values), sizeof(values));
          const std::uint8_t face_class = std::uint8_t(face.face_class);
          out.write(reinterpret_cast<const char*>(&face_class), 1);
        }
      },
      /*binary=*/true);
}

}  // namespace flysfm
