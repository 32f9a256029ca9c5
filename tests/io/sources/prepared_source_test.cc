#include "io/sources/prepared_source.h"

#include <catch2/catch.hpp>

#include "io/synthetic/synthetic_source.h"

namespace flysfm {
namespace {

TEST_CASE("Frames come prepared, in the source's order, as Engine::Prepare makes them") {
  SyntheticCaptureOptions capture_options;
  capture_options.num_views = 3;
  std::vector<Frame> frames = MakeSyntheticCapture(capture_options).frames;
  Frame bad;
  bad.name = "truncated.png";
  bad.bytes = std::vector<std::uint8_t>(frames[0].bytes.begin(), frames[0].bytes.begin() + 100);
  frames.insert(frames.begin() + 1, bad);

  const Engine::Options options;
  FrameListSource source(frames);
  PreparedFrameSource prepared(&source, options);
  for (const Frame& frame : frames) {
    std::optional<PreparedFrame> next = prepared.Next();
    REQUIRE(next);
    CHECK(next->frame.name == frame.name);
    const PreparedFrame expected = Engine::Prepare(frame, options);
    CHECK(next->error == expected.error);
    CHECK(next->features.size() == expected.features.size());
    CHECK(next->features.descriptors == expected.features.descriptors);
  }
  CHECK_FALSE(prepared.Next());
  CHECK_FALSE(prepared.Next());
}

}  // namespace
}  // namespace flysfm
