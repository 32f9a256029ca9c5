#include "io/sources/image_source.h"

#include <fstream>

#include <catch2/catch.hpp>
#include <opencv2/core.hpp>

#include "matching/image_decode.h"
#include "tests/testing/exif_jpeg.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

fs::path MakeFolder(const std::string& name, const std::vector<std::string>& files) {
  const fs::path dir = testing::MakeTempDir("image_source_" + name);
  for (const auto& file : files) std::ofstream(dir / file) << "x";
  return dir;
}

TEST_CASE("An image folder lists its images by name, any extension case") {
  const fs::path dir = MakeFolder(
      "folder", {"b.JPG", "a.png", "c.jpeg", "d.TIF", "e.tiff", "notes.txt", "f.bmp", "g.gif"});
  const auto frames = ListImageFolder(dir);
  std::vector<std::string> names;
  for (const auto& f : frames) names.push_back(f.name);
  CHECK(names ==
        std::vector<std::string>{"a.png", "b.JPG", "c.jpeg", "d.TIF", "e.tiff", "f.bmp"});
  CHECK(frames[1].path == dir / "b.JPG");
  CHECK(frames[1].timestamp == 1);
}

TEST_CASE("Missing or empty folders are clear errors") {
  using Catch::Matchers::Contains;
  CHECK_THROWS_WITH(ListImageFolder("/nonexistent/flysfm"), Contains("does not exist"));
  CHECK_THROWS_WITH(ListImageFolder(MakeFolder("empty", {"a.txt"})),
                    Contains("no images"));
}

TEST_CASE("A batch folder skips a symbolic link loop and reports it") {
  const fs::path dir = MakeFolder("loop", {"a.png", "b.png"});
  fs::create_symlink("loop.png", dir / "loop.png");
  std::vector<std::string> skipped;
  const std::vector<Frame> frames = ListBatchInput(dir, &skipped);
  REQUIRE(frames.size() == 2);
  CHECK(frames[1].name == "b.png");
  REQUIRE(skipped.size() == 1);
  CHECK_THAT(skipped[0], Catch::Contains("loop.png"));
}

TEST_CASE("A TUM sequence lists rgb.txt in order with its timestamps") {
  const fs::path dir = MakeFolder("tum", {});
  std::ofstream(dir / "rgb.txt") << "# color images\n# timestamp filename\n"
                                    "1305031102.211214 rgb/1305031102.211214.png\n"
                                    "1305031102.175304 rgb/1305031102.175304.png\n";
  const auto frames = ListBatchInput(dir);
  REQUIRE(frames.size() == 2);
  CHECK(frames[0].name == "rgb/1305031102.211214.png");
  CHECK(frames[0].timestamp == 1305031102.211214);
  CHECK(frames[1].path == dir / "rgb/1305031102.175304.png");
  std::ofstream(dir / "rgb.txt") << "1305031102.211214\n";
  CHECK_THROWS_WITH(ListTumSequence(dir), Catch::Matchers::Contains("rgb.txt:1"));
}

TEST_CASE("A frame's capture time comes from its file's EXIF or its bytes") {
  const fs::path dir = testing::MakeTempDir("image_source_time");
  testing::ExifTags tags;
  tags.texts = {{EXIF_TAG_DATE_TIME_ORIGINAL, "2024:05:17 10:30:15"},
                {EXIF_TAG_SUB_SEC_TIME_ORIGINAL, "5"}};
  // A large image, so that the file holds far more than the head read.
  cv::Mat image(1200, 1600, CV_8UC3);
  cv::randu(image, 0, 256);
  const std::vector<std::uint8_t> jpeg = testing::JpegWithExif(image, tags);
  REQUIRE(jpeg.size() > 256 * 1024);
  std::ofstream(dir / "a.jpg", std::ios::binary)
      .write(reinterpret_cast<const char*>(jpeg.data()), std::streamsize(jpeg.size()));
  Frame from_file;
  from_file.path = dir / "a.jpg";
  Frame from_bytes;
  from_bytes.bytes = jpeg;
  const std::optional<double> expected = ReadExifCaptureTime(jpeg.data(), jpeg.size());
  REQUIRE(expected);
  CHECK(*expected == Approx(1715941815.5));  // 2024-05-17 10:30:15.5 as seconds from 1970
  CHECK(ReadCaptureTime(from_file) == expected);
  CHECK(ReadCaptureTime(from_bytes) == expected);
  Frame missing;
  missing.path = dir / "gone.jpg";
  CHECK_FALSE(ReadCaptureTime(missing));
  Frame plain;
  plain.bytes = testing::WithoutExif(jpeg);
  CHECK_FALSE(ReadCaptureTime(plain));
}

TEST_CASE("Shuffling is a reproducible permutation") {
  std::vector<Frame> frames(50);
  for (int i = 0; i < 50; ++i) frames[i].name = std::to_string(i);
  auto a = frames, b = frames;
  ShuffleFrames(&a, 1);
  ShuffleFrames(&b, 1);
  std::vector<std::string> na, nb, sorted;
  for (int i = 0; i < 50; ++i) {
    na.push_back(a[i].name);
    nb.push_back(b[i].name);
  }
  CHECK(na == nb);
  bool moved = false;
  for (int i = 0; i < 50; ++i) moved |= na[i] != frames[i].name;
  CHECK(moved);
  std::sort(na.begin(), na.end());
  for (const auto& f : frames) sorted.push_back(f.name);
  std::sort(sorted.begin(), sorted.end());
  CHECK(na == sorted);
}

TEST_CASE("A paced source hands frames out at the interval") {
  std::vector<Frame> frames(3);
  FrameListSource source(frames, 0.05);
  std::vector<std::chrono::steady_clock::time_point> arrivals;
  while (auto frame = source.Next()) arrivals.push_back(frame->arrival);
  REQUIRE(arrivals.size() == 3);
  // Never early; lateness is bounded by scheduling, not asserted.
  CHECK(arrivals[2] - arrivals[0] >= std::chrono::milliseconds(100));
  CHECK_THROWS(FrameListSource({}, -1.0));
}

}  // namespace
}  // namespace flysfm
