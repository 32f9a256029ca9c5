#include "matching/image_decode.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include <catch2/catch.hpp>
#include <libexif/exif-data.h>
#include <opencv2/imgcodecs.hpp>

#include "io/synthetic/procedural_texture.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

std::vector<std::uint8_t> Encode(const cv::Mat& image, const std::string& extension) {
  std::vector<std::uint8_t> bytes;
  REQUIRE(cv::imencode(extension, image, bytes));
  return bytes;
}

TEST_CASE("PNG and JPEG bytes decode to the encoded image") {
  const cv::Mat image = MakeTexture(160, 120, 2, true);
  const DecodedImage png = DecodeImageBytes(Encode(image, ".png"));
  REQUIRE(png.ok());
  CHECK(cv::norm(png.image, image, cv::NORM_INF) == 0);  // lossless
  const DecodedImage jpeg = DecodeImageBytes(Encode(image, ".jpg"));
  REQUIRE(jpeg.ok());
  CHECK(jpeg.image.size() == image.size());
  CHECK(jpeg.image.type() == CV_8UC3);
  // A grey PNG comes back as BGR.
  cv::Mat grey;
  cv::extractChannel(image, grey, 0);
  const DecodedImage grey_png = DecodeImageBytes(Encode(grey, ".png"));
  REQUIRE(grey_png.ok());
  CHECK(grey_png.image.channels() == 3);
}

TEST_CASE("bad bytes give an error and never a crash") {
  const cv::Mat image = MakeTexture(160, 120, 3, true);
  const std::vector<std::uint8_t> png = Encode(image, ".png");
  const std::vector<std::uint8_t> jpeg = Encode(image, ".jpg");

  CHECK_FALSE(DecodeImageBytes(nullptr, 0).ok());
  CHECK_FALSE(DecodeImageBytes(std::vector<std::uint8_t>{}).ok());
  const DecodedImage truncated_png = DecodeImageBytes(png.data(), png.size() / 2);
  CHECK_FALSE(truncated_png.ok());
  CHECK_THAT(truncated_png.error, Catch::Contains("truncated"));
  CHECK_FALSE(DecodeImageBytes(jpeg.data(), jpeg.size() * 2 / 3).ok());
  // Headers only.
  CHECK_FALSE(DecodeImageBytes(png.data(), 8).ok());
  CHECK_FALSE(DecodeImageBytes(jpeg.data(), 3).ok());

  std::mt19937 rng(1);
  std::vector<std::uint8_t> noise(5000);
  for (auto& b : noise) b = std::uint8_t(rng());
  CHECK_FALSE(DecodeImageBytes(noise).ok());
  const std::string text = "definitely not an image";
  const DecodedImage from_text =
      DecodeImageBytes(reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
  CHECK_FALSE(from_text.ok());
  CHECK(from_text.image.empty());
  CHECK_FALSE(from_text.error.empty());

  // A JPEG whose body is corrupted but whose markers are intact.
  std::vector<std::uint8_t> corrupt = jpeg;
  for (std::size_t i = 20; i < corrupt.size() - 2; i += 7) corrupt[i] = 0xFF;
  CHECK_NOTHROW(DecodeImageBytes(corrupt));
}

TEST_CASE("image files are decoded and listed and missing ones give errors") {
  namespace fs = std::filesystem;
  const fs::path dir = testing::MakeTempDir("image_decode_test");
  const cv::Mat image = MakeTexture(64, 48, 4, true);
  REQUIRE(cv::imwrite((dir / "b.png").string(), image));
  REQUIRE(cv::imwrite((dir / "a.JPG").string(), image));
  std::ofstream((dir / "notes.txt").string()) << "x";
  std::ofstream((dir / "empty.png").string());

  CHECK(DecodeImageFile((dir / "b.png").string()).ok());
  const DecodedImage empty = DecodeImageFile((dir / "empty.png").string());
  CHECK_FALSE(empty.ok());
  CHECK_THAT(empty.error, Catch::Contains("empty.png"));
  CHECK_FALSE(DecodeImageFile((dir / "missing.png").string()).ok());

  const std::vector<std::string> files = ListImageFiles(dir.string());
  REQUIRE(files.size() == 3);
  CHECK(fs::path(files[0]).filename() == "a.JPG");
  CHECK(fs::path(files[1]).filename() == "b.png");
  CHECK_THROWS_AS(ListImageFiles((dir / "nope").string()), std::invalid_argument);
}

// A JPEG with an EXIF APP1 segment holding the given tags (SHORT values for
// FocalLengthIn35mmFilm and the resolution unit, RATIONAL for the others).
std::vector<std::uint8_t> JpegWithExif(const cv::Mat& image,
                                       const std::vector<std::pair<ExifTag, double>>& tags) {
  ExifData* exif = exif_data_new();
  exif_data_set_byte_order(exif, EXIF_BYTE_ORDER_INTEL);
  for (const auto& [tag, value] : tags) {
    ExifEntry* entry = exif_entry_new();
    exif_content_add_entry(exif->ifd[EXIF_IFD_EXIF], entry);
    exif_entry_initialize(entry, tag);
    if (entry->format == EXIF_FORMAT_SHORT) {
      exif_set_short(entry->data, EXIF_BYTE_ORDER_INTEL, ExifShort(value));
    } else if (entry->format == EXIF_FORMAT_LONG) {
      exif_set_long(entry->data, EXIF_BYTE_ORDER_INTEL, ExifLong(value));
    } else {
      exif_set_rational(entry->data, EXIF_BYTE_ORDER_INTEL,
                        ExifRational{ExifLong(value * 1000), 1000});
    }
    exif_entry_unref(entry);
  }
  unsigned char* block = nullptr;
  unsigned int length = 0;
  exif_data_save_data(exif, &block, &length);
  exif_data_unref(exif);
  REQUIRE(block != nullptr);
  std::vector<std::uint8_t> jpeg = Encode(image, ".jpg");
  // APP1 right after the start-of-image marker; its length counts itself.
  std::vector<std::uint8_t> app1 = {0xFF, 0xE1, std::uint8_t((length + 2) >> 8),
                                    std::uint8_t((length + 2) & 0xFF)};
  app1.insert(app1.end(), block, block + length);
  free(block);
  jpeg.insert(jpeg.begin() + 2, app1.begin(), app1.end());
  return jpeg;
}

TEST_CASE("the focal length in pixels comes from a JPEG's EXIF when it says enough") {
  const cv::Mat image = MakeTexture(640, 480, 3);
  SECTION("35 mm equivalent at 4:3: the same diagonal field of view as on film") {
    const DecodedImage decoded =
        DecodeImageBytes(JpegWithExif(image, {{EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM, 50}}));
    REQUIRE(decoded.ok());
    REQUIRE(decoded.exif_focal_length_px);
    // 800 px of diagonal for the film's 43.27 mm.
    CHECK(*decoded.exif_focal_length_px == Approx(50.0 * 800 / std::hypot(36.0, 24.0)));
  }
  SECTION("35 mm equivalent at 3:2: the film's width maps to the longer side") {
    const DecodedImage decoded = DecodeImageBytes(JpegWithExif(
        MakeTexture(600, 400, 3), {{EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM, 24}}));
    REQUIRE(decoded.exif_focal_length_px);
    CHECK(*decoded.exif_focal_length_px == Approx(24.0 / 36.0 * 600));
  }
  SECTION("focal plane resolution in inches, the default unit") {
    // 35 mm at 4 000 px/inch on a sensor as wide as the image: 5 512 px.
    const DecodedImage decoded = DecodeImageBytes(
        JpegWithExif(image, {{EXIF_TAG_FOCAL_LENGTH, 35},
                             {EXIF_TAG_FOCAL_PLANE_X_RESOLUTION, 4000},
                             {EXIF_TAG_FOCAL_PLANE_RESOLUTION_UNIT, 2}}));
    REQUIRE(decoded.exif_focal_length_px);
    CHECK(*decoded.exif_focal_length_px == Approx(35 * 4000 / 25.4));
  }
  SECTION("absurd values give none") {
    // 1 mm equivalent, and a 5 000 mm one.
    CHECK_FALSE(DecodeImageBytes(JpegWithExif(image, {{EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM, 1}}))
                    .exif_focal_length_px);
    CHECK_FALSE(
        DecodeImageBytes(JpegWithExif(image, {{EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM, 5000}}))
            .exif_focal_length_px);
  }
  SECTION("focal length in mm and the focal plane's resolution") {
    // 5.8 mm at 2 000 px/cm on a sensor 1 280 px wide, stored at 640: 580 px.
    const DecodedImage decoded = DecodeImageBytes(
        JpegWithExif(image, {{EXIF_TAG_FOCAL_LENGTH, 5.8},
                             {EXIF_TAG_FOCAL_PLANE_X_RESOLUTION, 2000},
                             {EXIF_TAG_FOCAL_PLANE_RESOLUTION_UNIT, 3},
                             {EXIF_TAG_PIXEL_X_DIMENSION, 1280}}));
    REQUIRE(decoded.exif_focal_length_px);
    CHECK(*decoded.exif_focal_length_px == Approx(5.8 * 200 * 0.5));
  }
  SECTION("a focal length in mm alone, no EXIF, or a PNG give none") {
    CHECK_FALSE(DecodeImageBytes(JpegWithExif(image, {{EXIF_TAG_FOCAL_LENGTH, 5.8}}))
                    .exif_focal_length_px);
    CHECK_FALSE(DecodeImageBytes(Encode(image, ".jpg")).exif_focal_length_px);
    CHECK_FALSE(DecodeImageBytes(Encode(image, ".png")).exif_focal_length_px);
  }
}

}  // namespace
}  // namespace flysfm
