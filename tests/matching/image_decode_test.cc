#include "matching/image_decode.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <random>

#include <catch2/catch.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/synthetic/procedural_texture.h"
#include "tests/testing/exif_jpeg.h"
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

TEST_CASE("the grey image is full size, a JPEG's colour is reduced as far as asked") {
  // Odd sizes: libjpeg rounds each reduced side up.
  const cv::Mat image = MakeTexture(1001, 701, 4, true);
  const std::vector<std::uint8_t> jpeg = Encode(image, ".jpg");
  const DecodedImage full = DecodeImageBytes(jpeg);
  REQUIRE(full.ok());
  CHECK(full.colour_reduction == 1);
  CHECK(full.image.size() == image.size());
  cv::Mat full_grey;
  cv::cvtColor(full.image, full_grey, cv::COLOR_BGR2GRAY);
  CHECK(cv::norm(full.grey, full_grey, cv::NORM_INF) == 0);

  // long side 1001: /2 gives 501, /4 251, /8 126 pixels.
  for (const auto& [long_side, reduction] :
       std::vector<std::pair<int, int>>{{1001, 1}, {501, 2}, {300, 2}, {251, 4}, {200, 4},
                                        {126, 8}, {1, 8}}) {
    CAPTURE(long_side);
    const DecodedImage reduced = DecodeImageBytes(jpeg, DecodeOptions(), long_side);
    REQUIRE(reduced.ok());
    CHECK(reduced.colour_reduction == reduction);
    CHECK(reduced.image.cols == (1001 + reduction - 1) / reduction);
    CHECK(reduced.image.rows == (701 + reduction - 1) / reduction);
    // The luma alone decodes to the grey of the colour decode, give or take
    // rounding in the colour conversion.
    REQUIRE(reduced.grey.size() == image.size());
    CHECK(cv::norm(reduced.grey, full_grey, cv::NORM_INF) <= 1);
    // The reduced colour is the full one averaged over reduction x reduction
    // blocks (the DCT's low frequencies), away from the rounded-up edge.
    const int w = 1001 / reduction;
    const int h = 701 / reduction;
    cv::Mat averaged;
    cv::resize(full.image(cv::Rect(0, 0, w * reduction, h * reduction)), averaged,
               cv::Size(w, h), 0, 0, cv::INTER_AREA);
    cv::Mat difference;
    cv::absdiff(reduced.image(cv::Rect(0, 0, w, h)), averaged, difference);
    CHECK(cv::mean(difference)[0] < 3.0);
  }
  // A PNG is decoded once, at full size.
  const DecodedImage png = DecodeImageBytes(Encode(image, ".png"), DecodeOptions(), 100);
  REQUIRE(png.ok());
  CHECK(png.colour_reduction == 1);
  CHECK(png.image.size() == image.size());
  CHECK(png.grey.size() == image.size());
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

// The offset of the first SOF0 segment's height field (FF C0, length,
// precision, then height and width, big-endian) in an encoder's JPEG.
std::size_t Sof0SizeOffset(const std::vector<std::uint8_t>& jpeg) {
  for (std::size_t i = 2; i + 9 <= jpeg.size(); ++i) {
    if (jpeg[i] == 0xFF && jpeg[i + 1] == 0xC0) return i + 5;
  }
  FAIL("no SOF0 segment");
  return 0;
}

void PutBigEndian16(std::uint8_t* at, int value) {
  at[0] = std::uint8_t(value >> 8);
  at[1] = std::uint8_t(value);
}

TEST_CASE("a JPEG or PNG claiming too many pixels is rejected before decoding") {
  const cv::Mat image = MakeTexture(64, 48, 5, true);
  std::vector<std::uint8_t> jpeg = Encode(image, ".jpg");
  const std::size_t size_at = Sof0SizeOffset(jpeg);
  std::optional<ImageSize> size = ReadImageSize(jpeg.data(), jpeg.size());
  REQUIRE(size);
  CHECK(size->width == 64);
  CHECK(size->height == 48);

  // 20000 x 15000 (300 MP) stays below OpenCV's own limit (2^30 pixels), so
  // only the header check keeps the decoder from allocating 900 MB.
  PutBigEndian16(&jpeg[size_at], 15000);
  PutBigEndian16(&jpeg[size_at + 2], 20000);
  size = ReadImageSize(jpeg.data(), jpeg.size());
  REQUIRE(size);
  CHECK(size->width == 20000);
  CHECK(size->height == 15000);
  const DecodedImage bomb = DecodeImageBytes(jpeg);
  CHECK_FALSE(bomb.ok());
  CHECK_THAT(bomb.error, Catch::Contains("20000 x 15000") && Catch::Contains("max_image_pixels"));
  PutBigEndian16(&jpeg[size_at], 60000);
  PutBigEndian16(&jpeg[size_at + 2], 60000);
  CHECK_THAT(DecodeImageBytes(jpeg).error, Catch::Contains("max_image_pixels"));

  std::vector<std::uint8_t> png = Encode(image, ".png");
  png[16] = png[17] = png[20] = png[21] = 0x7F;  // width and height about 2^30
  const DecodedImage png_bomb = DecodeImageBytes(png);
  CHECK_THAT(png_bomb.error, Catch::Contains("max_image_pixels"));

  // The bound is an option.
  DecodeOptions options;
  CHECK(options.Check());
  options.max_image_pixels = 64 * 48 - 1;
  CHECK_FALSE(DecodeImageBytes(Encode(image, ".jpg"), options).ok());
  CHECK_FALSE(DecodeImageBytes(Encode(image, ".png"), options).ok());
  options.max_image_pixels = 64 * 48;
  CHECK(DecodeImageBytes(Encode(image, ".jpg"), options).ok());
  options.max_image_pixels = 0;
  std::string error;
  CHECK_FALSE(options.Check(&error));
  CHECK_THAT(error, Catch::Contains("max_image_pixels"));
}

TEST_CASE("the header reader stays inside cut and hostile headers") {
  const std::vector<std::uint8_t> jpeg = Encode(MakeTexture(64, 48, 6, true), ".jpg");
  const std::size_t size_at = Sof0SizeOffset(jpeg);
  // Every cut before the frame header's width ends says nothing (ASan checks
  // that no byte past the cut is read).
  for (std::size_t cut = 0; cut < size_at + 4; ++cut) {
    const std::vector<std::uint8_t> head(jpeg.begin(), jpeg.begin() + std::ptrdiff_t(cut));
    CHECK_FALSE(ReadImageSize(head.data(), head.size()));
  }
  // Segment lengths pointing past the end, or too short to move on.
  for (const int length : {0, 1, 0xFFFF}) {
    std::vector<std::uint8_t> hostile = {0xFF, 0xD8, 0xFF, 0xE0};
    hostile.push_back(std::uint8_t(length >> 8));
    hostile.push_back(std::uint8_t(length));
    hostile.insert(hostile.end(), {0xFF, 0xD9});
    CHECK_FALSE(ReadImageSize(hostile.data(), hostile.size()));
    CHECK_FALSE(DecodeImageBytes(hostile).ok());
  }
  // Random bytes behind a JPEG start: no crash, a counted failure.
  std::mt19937 rng(2);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<std::uint8_t> noise(64 + rng() % 512);
    for (auto& b : noise) b = std::uint8_t(rng() % 4 == 0 ? 0xFF : rng());
    noise[0] = 0xFF;
    noise[1] = 0xD8;
    noise[2] = 0xFF;
    noise[noise.size() - 2] = 0xFF;
    noise.back() = 0xD9;
    ReadImageSize(noise.data(), noise.size());
    CHECK_FALSE(DecodeImageBytes(noise).ok());
  }
}

TEST_CASE("a file over max_file_bytes is not read") {
  const std::filesystem::path dir = testing::MakeTempDir("image_decode_large");
  const std::filesystem::path path = dir / "a.png";
  const std::vector<std::uint8_t> png = Encode(MakeTexture(64, 48, 7, true), ".png");
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(png.data()), std::streamsize(png.size()));
  DecodeOptions options;
  CHECK(DecodeImageFile(path.string(), options).ok());
  options.max_file_bytes = png.size() - 1;
  const DecodedImage large = DecodeImageFile(path.string(), options);
  CHECK_FALSE(large.ok());
  CHECK_THAT(large.error, Catch::Contains("max_file_bytes"));
  CHECK_FALSE(ReadImageFileBytes(path.string(), png.size() - 1));
  CHECK(ReadImageFileBytes(path.string(), png.size()) == png);
}

TEST_CASE("an entry that cannot be examined is skipped and reported, not fatal") {
  namespace fs = std::filesystem;
  const fs::path dir = testing::MakeTempDir("image_decode_loop");
  REQUIRE(cv::imwrite((dir / "a.png").string(), MakeTexture(64, 48, 8, true)));
  fs::create_symlink("loop.jpg", dir / "loop.jpg");  // ELOOP when followed
  std::vector<std::string> skipped;
  const std::vector<std::string> files = ListImageFiles(dir.string(), &skipped);
  REQUIRE(files.size() == 1);
  CHECK(fs::path(files[0]).filename() == "a.png");
  REQUIRE(skipped.size() == 1);
  CHECK_THAT(skipped[0], Catch::Contains("loop.jpg"));
  CHECK(ListImageFiles(dir.string()).size() == 1);
}

std::vector<std::uint8_t> JpegWithExif(const cv::Mat& image,
                                       std::vector<std::pair<ExifTag, double>> numbers) {
  return testing::JpegWithExif(image, {std::move(numbers), {}});
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

TEST_CASE("EXIF tells camera bodies, lenses and zoom settings apart") {
  const cv::Mat image = MakeTexture(320, 240, 4);
  const auto identity = [&](testing::ExifTags tags) {
    const DecodedImage decoded = DecodeImageBytes(testing::JpegWithExif(image, tags));
    REQUIRE(decoded.ok());
    return decoded.camera_identity;
  };
  const std::vector<std::pair<ExifTag, std::string>> body = {{EXIF_TAG_MAKE, "Canon"},
                                                             {EXIF_TAG_MODEL, "EOS 5D"}};
  const std::string plain = identity({{}, body});
  CHECK(plain.find("Canon") != std::string::npos);
  CHECK(plain.find("EOS 5D") != std::string::npos);
  // Another body, another lens, another serial number, another zoom
  // setting: each another camera.
  CHECK(identity({{}, {{EXIF_TAG_MAKE, "Canon"}, {EXIF_TAG_MODEL, "EOS R5"}}}) != plain);
  auto with_lens = body;
  with_lens.emplace_back(EXIF_TAG_LENS_MODEL, "EF24-70mm f/2.8L");
  const std::string lens = identity({{}, with_lens});
  CHECK(lens != plain);
  auto with_serial = body;
  with_serial.emplace_back(EXIF_TAG_BODY_SERIAL_NUMBER, "0123");
  CHECK(identity({{}, with_serial}) != plain);
  CHECK(identity({{{EXIF_TAG_FOCAL_LENGTH, 24}}, with_lens}) !=
        identity({{{EXIF_TAG_FOCAL_LENGTH, 70}}, with_lens}));
  CHECK(identity({{{EXIF_TAG_FOCAL_LENGTH, 24}}, with_lens}) ==
        identity({{{EXIF_TAG_FOCAL_LENGTH, 24}}, with_lens}));
  // Hostile text stays printable and bounded.
  const std::string hostile = identity({{}, {{EXIF_TAG_MODEL, std::string(500, 'x') + "\n\t\x01"}}});
  CHECK(hostile.size() <= 200);
  CHECK(std::all_of(hostile.begin(), hostile.end(),
                    [](unsigned char c) { return c >= 0x20 && c < 0x7F; }));
  // Without EXIF: no identity (the image size alone then tells cameras apart).
  CHECK(DecodeImageBytes(Encode(image, ".jpg")).camera_identity.empty());
}


TEST_CASE("ReadExif reads a whole JPEG and its APP1 payload alone alike") {
  testing::ExifTags tags;
  tags.numbers = {{EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM, 24}, {EXIF_TAG_FOCAL_LENGTH, 8.8}};
  tags.texts = {{EXIF_TAG_MAKE, "DJI"}, {EXIF_TAG_MODEL, "FC6310"}};
  const std::vector<std::uint8_t> jpeg = testing::JpegWithExif(MakeTexture(60, 40, 3), tags);
  // JpegWithExif puts APP1 right after SOI; its length counts itself.
  REQUIRE(jpeg.size() > 6);
  REQUIRE(jpeg[3] == 0xE1);
  const std::size_t app1_length = std::size_t(jpeg[4]) << 8 | jpeg[5];
  const std::vector<std::uint8_t> payload(jpeg.begin() + 6, jpeg.begin() + 4 + app1_length);
  // The pixel size is the caller's: a 3:2 image 6 000 px wide.
  for (const auto& bytes : {jpeg, payload}) {
    const ExifFields fields = ReadExif(bytes.data(), bytes.size(), 6000, 4000);
    REQUIRE(fields.focal_length_px);
    CHECK(*fields.focal_length_px == Approx(24.0 / 36.0 * 6000));
    CHECK(fields.camera_identity == "DJI|FC6310|||8.8 mm");
  }
  // The same fields as DecodeImageBytes gives, at the decoded size.
  const DecodedImage decoded = DecodeImageBytes(jpeg);
  REQUIRE(decoded.ok());
  const ExifFields at_size = ReadExif(payload.data(), payload.size(), 60, 40);
  CHECK(at_size.focal_length_px == decoded.exif_focal_length_px);
  CHECK(at_size.camera_identity == decoded.camera_identity);
  // No EXIF, cut short, empty, or a degenerate image size: no fields, no crash.
  const std::vector<std::uint8_t> plain = testing::WithoutExif(jpeg);
  CHECK_FALSE(ReadExif(plain.data(), plain.size(), 60, 40).focal_length_px);
  CHECK(ReadExif(plain.data(), plain.size(), 60, 40).camera_identity.empty());
  CHECK_FALSE(ReadExif(payload.data(), 10, 60, 40).focal_length_px);
  CHECK_FALSE(ReadExif(nullptr, 0, 60, 40).focal_length_px);
  CHECK_FALSE(ReadExif(payload.data(), payload.size(), 0, 0).focal_length_px);
}

// Seconds from 1970 of a UTC calendar time, by the C library (timegm), as
// the ground truth of the EXIF reader's own calendar arithmetic.
double UtcSeconds(int year, int month, int day, int hour, int minute, int second) {
  std::tm time{};
  time.tm_year = year - 1900;
  time.tm_mon = month - 1;
  time.tm_mday = day;
  time.tm_hour = hour;
  time.tm_min = minute;
  time.tm_sec = second;
  return double(timegm(&time));
}

TEST_CASE("ReadExifCaptureTime reads DateTimeOriginal with its sub-seconds") {
  const cv::Mat image = MakeTexture(60, 40, 3);
  const auto time_of = [&](std::vector<std::pair<ExifTag, std::string>> texts) {
    testing::ExifTags tags;
    tags.texts = std::move(texts);
    const std::vector<std::uint8_t> jpeg = testing::JpegWithExif(image, tags);
    return ReadExifCaptureTime(jpeg.data(), jpeg.size());
  };
  const std::optional<double> whole =
      time_of({{EXIF_TAG_DATE_TIME_ORIGINAL, "2024:05:17 10:30:15"}});
  REQUIRE(whole);
  CHECK(*whole == UtcSeconds(2024, 5, 17, 10, 30, 15));
  // Before 1970 and across a leap day, too.
  CHECK(time_of({{EXIF_TAG_DATE_TIME_ORIGINAL, "1969:12:31 23:59:59"}}) ==
        std::optional<double>(-1.0));
  CHECK(time_of({{EXIF_TAG_DATE_TIME_ORIGINAL, "2024:03:01 00:00:00"}}) ==
        std::optional<double>(UtcSeconds(2024, 3, 1, 0, 0, 0)));
  const std::optional<double> fine = time_of({{EXIF_TAG_DATE_TIME_ORIGINAL, "2024:05:17 10:30:15"},
                                              {EXIF_TAG_SUB_SEC_TIME_ORIGINAL, "05"}});
  REQUIRE(fine);
  CHECK(*fine - *whole == Approx(0.05).margin(1e-6));
  // Two shots in the same second keep their order through the sub-seconds.
  CHECK(*time_of({{EXIF_TAG_DATE_TIME_ORIGINAL, "2024:05:17 10:30:15"},
                  {EXIF_TAG_SUB_SEC_TIME_ORIGINAL, "9"}}) > *fine);
  // No time: no tag, an unset clock, a malformed date, no EXIF at all.
  CHECK_FALSE(time_of({{EXIF_TAG_MAKE, "Canon"}}));
  CHECK_FALSE(time_of({{EXIF_TAG_DATE_TIME_ORIGINAL, "0000:00:00 00:00:00"}}));
  CHECK_FALSE(time_of({{EXIF_TAG_DATE_TIME_ORIGINAL, "2024:13:01 00:00:00"}}));
  CHECK_FALSE(time_of({{EXIF_TAG_DATE_TIME_ORIGINAL, "yesterday"}}));
  const std::vector<std::uint8_t> plain = Encode(image, ".jpg");
  CHECK_FALSE(ReadExifCaptureTime(plain.data(), plain.size()));
  CHECK_FALSE(ReadExifCaptureTime(nullptr, 0));
}

}  // namespace
}  // namespace flysfm
