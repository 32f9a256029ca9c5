#include "io/sources/image_markers.h"

#include <catch2/catch.hpp>
#include <opencv2/imgcodecs.hpp>

namespace flysfm {
namespace {

std::vector<std::uint8_t> Encode(const std::string& extension) {
  cv::Mat image(32, 32, CV_8UC3, cv::Scalar(10, 200, 30));
  std::vector<std::uint8_t> bytes;
  REQUIRE(cv::imencode(extension, image, bytes));
  return bytes;
}

TEST_CASE("A whole JPEG passes and a cut one does not") {
  std::vector<std::uint8_t> jpeg = Encode(".jpg");
  CHECK(HasJpegMarkers(jpeg));
  CHECK(LooksCompleteImage("a.JPG", jpeg));
  std::vector<std::uint8_t> padded = jpeg;
  padded.resize(padded.size() + 16, 0);
  CHECK(HasJpegMarkers(padded));
  jpeg.resize(jpeg.size() - 1);
  CHECK_FALSE(HasJpegMarkers(jpeg));
  CHECK_FALSE(HasJpegMarkers({}));
}

TEST_CASE("A whole PNG passes and a cut one does not") {
  std::vector<std::uint8_t> png = Encode(".png");
  CHECK(HasPngMarkers(png));
  CHECK(LooksCompleteImage("a.png", png));
  png.resize(png.size() - 4);
  CHECK_FALSE(LooksCompleteImage("a.png", png));
  CHECK_FALSE(HasJpegMarkers(Encode(".png")));
}

}  // namespace
}  // namespace flysfm
