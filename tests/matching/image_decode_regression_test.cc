// EXIF focal lengths of real photos against their calibration.

#include "matching/image_decode.h"

#include <fstream>

#include <catch2/catch.hpp>

#include "tests/testing/data.h"

namespace flysfm {
namespace {

TEST_CASE("sceaux_castle: the EXIF focal length is within 10 % of the calibrated one") {
  // images/K.txt, row-major 3x3: fx at (0, 0).
  std::ifstream k_file(testing::DataPath("sceaux_castle/images/K.txt"));
  double calibrated_focal = 0;
  REQUIRE(k_file >> calibrated_focal);
  const std::vector<std::string> files =
      ListImageFiles(testing::DataPath("sceaux_castle/images"));
  REQUIRE(files.size() == 11);
  for (const std::string& file : files) {
    const DecodedImage decoded = DecodeImageFile(file);
    INFO(file);
    REQUIRE(decoded.ok());
    REQUIRE(decoded.exif_focal_length_px);
    // The EXIF says a 35 mm equivalent rounded to whole millimetres, and the
    // lens's true focal length differs from its nominal one by a few percent.
    CHECK(*decoded.exif_focal_length_px == Approx(calibrated_focal).epsilon(0.10));
  }
}

}  // namespace
}  // namespace flysfm
