#include "io/run/checkpoint.h"

#include <fstream>
#include <iterator>

#include <catch2/catch.hpp>

#include "io/synthetic/synthetic_source.h"
#include "tests/testing/frame_files.h"
#include "tests/testing/temp_dir.h"
#include "tests/testing/rendered_capture.h"
#include "tests/testing/sanitizer.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

struct Walk {
  Camera camera;
  std::vector<Frame> frames;  // as files
};

const Walk& RenderedWalk() {
  static const Walk walk = [] {
    SyntheticCaptureOptions options;
    options.num_views = testing::kSanitizerBuild ? 8 : 10;  // tests/testing/sanitizer.h
    options.seed = 8;
    const SyntheticCapture capture = testing::RenderedCapture(options);
    return Walk{capture.camera,
                testing::WriteFrameFiles(capture.frames, testing::MakeTempDir("checkpoint_frames"))};
  }();
  return walk;
}

TEST_CASE("Each image's record and windows are written once, the snapshot within its share") {
  const Walk& walk = RenderedWalk();
  const fs::path dir = testing::MakeTempDir("checkpoint") / "state";
  // A share so small that after the first snapshot only the final one is
  // due: a crash before it resumes from the first image.
  Checkpointer::Options options;
  options.max_snapshot_share = 1e-9;
  Checkpointer checkpointer(dir, options);
  CHECK_FALSE(checkpointer.Exists());
  Engine engine(Engine::Options(), walk.camera);
  for (const Frame& frame : walk.frames) {
    engine.AddImage(frame);
    checkpointer.Update(engine, 100.0);
  }
  CHECK(checkpointer.summary().num_snapshots == 1);
  for (const auto& [image_id, image] : engine.reconstruction().images()) {
    CHECK(fs::exists(dir / "images" / (std::to_string(image_id) + ".bin")));
    // The images are files, from which a restore cuts their windows again.
    CHECK(engine.HasImageFile(image_id));
    CHECK_FALSE(fs::exists(dir / "windows" / (std::to_string(image_id) + ".bin")));
  }
  {
    // Images that came as bytes alone have their windows written.
    const fs::path bytes_dir = testing::MakeTempDir("checkpoint_bytes") / "state";
    Checkpointer bytes_checkpointer(bytes_dir, options);
    Engine bytes_engine(Engine::Options(), walk.camera);
    for (Frame frame : walk.frames) {
      std::ifstream file(frame.path, std::ios::binary);
      frame.bytes.assign(std::istreambuf_iterator<char>(file), {});
      frame.path.clear();
      bytes_engine.AddImage(frame);
      bytes_checkpointer.Update(bytes_engine, 100.0);
    }
    const LsmImageStore& lsm = bytes_engine.lsm_images();
    int num_windows = 0;
    for (const auto& [image_id, image] : bytes_engine.reconstruction().images()) {
      const bool written = fs::exists(bytes_dir / "windows" / (std::to_string(image_id) + ".bin"));
      CHECK(written == (lsm.HasPixels(image_id) && !lsm.IsWhole(image_id)));
      num_windows += written;
    }
    CHECK(num_windows > 0);
  }

  // The first snapshot held one image: the restart goes on from there, and
  // the later images come again.
  {
    Checkpointer restart(dir, options);
    Engine resumed(Engine::Options(), walk.camera);
    restart.Restore(&resumed);
    CHECK(resumed.reconstruction().images().size() == 1);
    for (std::size_t i = 1; i < walk.frames.size(); ++i) {
      resumed.AddImage(walk.frames[i]);
      restart.Update(resumed, 100.0);
    }
    CHECK(resumed.reconstruction().NumRegisteredImages() == walk.frames.size());
  }

  // The final snapshot holds everything.
  checkpointer.Update(engine, 0.0, /*final=*/true);
  CHECK(checkpointer.summary().num_snapshots == 2);
  // The retrieval model learnt from the session is kept in the version the
  // snapshot names, older ones removed.
  const auto model_files = std::distance(fs::directory_iterator(dir / "retrieval"),
                                         fs::directory_iterator());
  CHECK(model_files == 1);
  CHECK(fs::exists(dir / "retrieval" /
                   (std::to_string(engine.RetrievalModelVersion()) + ".bin")));
  Checkpointer restart(dir, options);
  Engine resumed(Engine::Options(), walk.camera);
  restart.Restore(&resumed);
  CHECK(resumed.reconstruction().NumRegisteredImages() == walk.frames.size());
  CHECK(resumed.reconstruction().NumPoints3D() == engine.reconstruction().NumPoints3D());

  // A snapshot is written only when the engine's state changed.
  options.max_snapshot_share = 1;
  Checkpointer every(testing::MakeTempDir("checkpoint_every") / "state", options);
  every.Update(engine, 1e6);
  every.Update(engine, 1e6);
  CHECK(every.summary().num_snapshots == 1);  // nothing new: no snapshot
  CHECK(every.summary().bytes > 0);
}

TEST_CASE("A checkpoint that cannot be written is reported, and the next update completes it") {
  const Walk& walk = RenderedWalk();
  const fs::path parent = testing::MakeTempDir("checkpoint_blocked");
  // A file where the folder should be: every write fails.
  std::ofstream(parent / "state") << "in the way";
  Checkpointer checkpointer(parent / "state", Checkpointer::Options());
  Engine engine(Engine::Options(), walk.camera);
  engine.AddImage(walk.frames[0]);
  engine.AddImage(walk.frames[1]);
  CHECK_THROWS_AS(checkpointer.Update(engine, 100.0), std::runtime_error);
  fs::remove(parent / "state");
  checkpointer.Update(engine, 100.0);
  Engine resumed(Engine::Options(), walk.camera);
  checkpointer.Restore(&resumed);
  CHECK(resumed.reconstruction().images().size() == 2);
}

TEST_CASE("Clear starts a new checkpoint, a bad share is refused") {
  const fs::path dir = testing::MakeTempDir("checkpoint_clear") / "state";
  fs::create_directories(dir);
  std::ofstream(dir / "snapshot.bin") << "old";
  Checkpointer checkpointer(dir, Checkpointer::Options());
  CHECK(checkpointer.Exists());
  checkpointer.Clear();
  CHECK_FALSE(checkpointer.Exists());
  Checkpointer::Options bad;
  bad.max_snapshot_share = 0;
  CHECK_THROWS_AS(Checkpointer(dir, bad), std::invalid_argument);
}

}  // namespace
}  // namespace flysfm
