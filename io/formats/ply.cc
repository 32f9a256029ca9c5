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

}  // namespace flysfm
