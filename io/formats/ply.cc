#include "io/formats/ply.h"

#include "io/formats/atomic_file.h"

namespace flysfm {

void WritePly(const Reconstruction& reconstruction, const std::filesystem::path& path) {
  WriteFileAtomically(
      path,
      [&](std::ostream& out) {
        out << "ply\nformat binary_little_endian 1.0\n"
            << "element vertex " << reconstruction.NumPoints3D() << "\n"
            << "property double x\nproperty double y\nproperty double z\n"
               "property uchar red\nproperty uchar green\nproperty uchar blue\n"
               "end_header\n";
        for (const auto& [id, point] : reconstruction.points3D()) {
          out.write(reinterpret_cast<const char*>(point.xyz.data()), 3 * sizeof(double));
          out.write(reinterpret_cast<const char*>(point.color.data()), 3);
        }
      },
      /*binary=*/true);
}

}  // namespace flysfm
