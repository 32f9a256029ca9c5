#include "io/run/checkpoint.h"

#include <chrono>
#include <fstream>
#include <stdexcept>

#include "io/formats/atomic_file.h"

namespace flysfm {
namespace {

// Counts what a writer puts through, so the summary can say how much a
// checkpoint writes.
class CountingBuffer : public std::streambuf {
 public:
  explicit CountingBuffer(std::streambuf* target) : target_(target) {}
  std::size_t count() const { return count_; }

 protected:
  std::streamsize xsputn(const char* data, std::streamsize size) override {
    count_ += std::size_t(size);
    return target_->sputn(data, size);
  }
  int_type overflow(int_type c) override {
    if (traits_type::eq_int_type(c, traits_type::eof())) return traits_type::not_eof(c);
    ++count_;
    return target_->sputc(traits_type::to_char_type(c));
  }

 private:
  std::streambuf* target_;
  std::size_t count_ = 0;
};

// Writes `path` atomically; returns the bytes written.
std::size_t WriteBinary(const std::filesystem::path& path,
                        const std::function<void(std::ostream&)>& write) {
  std::size_t bytes = 0;
  WriteFileAtomically(
      path,
      [&](std::ostream& out) {
        CountingBuffer counting(out.rdbuf());
        std::ostream counted(&counting);
        write(counted);
        if (!counted) throw std::runtime_error("write failed");
        bytes = counting.count();
      },
      /*binary=*/true);
  return bytes;
}

std::unique_ptr<std::istream> OpenBinary(const std::filesystem::path& path) {
  auto in = std::make_unique<std::ifstream>(path, std::ios::binary);
  if (!*in) return nullptr;
  return in;
}

double MillisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace

Checkpointer::Checkpointer(std::filesystem::path dir, const Options& options)
    : dir_(std::move(dir)), options_(options) {
  if (!options_.Check()) {
    throw std::invalid_argument("invalid checkpoint option: max_snapshot_share (0, 1]");
  }
}

bool Checkpointer::Exists() const { return std::filesystem::exists(dir_ / "snapshot.bin"); }

std::filesystem::path Checkpointer::ImageFile(const char* folder, image_t image_id) const {
  return dir_ / folder / (std::to_string(image_id) + ".bin");
}

void Checkpointer::Restore(Engine* engine) {
  const std::unique_ptr<std::istream> snapshot = OpenBinary(dir_ / "snapshot.bin");
  if (!snapshot) throw std::runtime_error("cannot read " + (dir_ / "snapshot.bin").string());
  Engine::CheckpointFiles files;
  files.record = [this](image_t image_id) { return OpenBinary(ImageFile("images", image_id)); };
  files.windows = [this](image_t image_id) { return OpenBinary(ImageFile("windows", image_id)); };
  files.retrieval_model = [this](int version) {
    return OpenBinary(ImageFile("retrieval", image_t(version)));
  };
  engine->Restore(*snapshot, files);
  retrieval_model_version_ = engine->RetrievalModelVersion();
  const auto& images = engine->reconstruction().images();
  last_recorded_ = images.empty() ? 0 : images.rbegin()->first;
  awaiting_windows_.clear();
  for (const image_t image_id : engine->lsm_images().WholeImages()) {
    awaiting_windows_.insert(image_id);
  }
  engine_ms_since_snapshot_ = 0;
}

void Checkpointer::Clear() {
  std::filesystem::remove_all(dir_);
  folders_made_ = false;
  last_recorded_ = 0;
  retrieval_model_version_ = 0;
  awaiting_windows_.clear();
  engine_ms_since_snapshot_ = 0;
}

void Checkpointer::Update(const Engine& engine, double engine_ms, bool final) {
  engine_ms_since_snapshot_ += engine_ms;
  auto start = std::chrono::steady_clock::now();
  if (!folders_made_) {
    for (const char* folder : {"images", "windows", "retrieval"}) {
      std::filesystem::create_directories(dir_ / folder);
    }
    folders_made_ = true;
  }
  const auto& images = engine.reconstruction().images();
  for (auto it = images.upper_bound(last_recorded_); it != images.end(); ++it) {
    const image_t image_id = it->first;
    summary_.bytes += WriteBinary(ImageFile("images", image_id), [&](std::ostream& out) {
      engine.WriteImageRecord(image_id, out);
    });
    last_recorded_ = image_id;
    awaiting_windows_.insert(image_id);
    snapshot_due_ = true;
  }
  const LsmImageStore& lsm = engine.lsm_images();
  for (auto it = awaiting_windows_.begin(); it != awaiting_windows_.end();) {
    const image_t image_id = *it;
    if (lsm.IsWhole(image_id)) {
      ++it;
      continue;
    }
    // An image from a file gets its windows cut from it again at a restore:
    // at 24 MP they are 6 MB, its record 0.2 MB.
    if (lsm.HasPixels(image_id) && !engine.HasImageFile(image_id)) {
      summary_.bytes += WriteBinary(ImageFile("windows", image_id), [&](std::ostream& out) {
        lsm.WriteWindows(image_id, out);
      });
    }
    it = awaiting_windows_.erase(it);
  }
  const int model_version = engine.RetrievalModelVersion();
  if (model_version != retrieval_model_version_) {
    summary_.bytes += WriteBinary(ImageFile("retrieval", image_t(model_version)),
                                  [&](std::ostream& out) { engine.WriteRetrievalModel(out); });
    retrieval_model_version_ = model_version;
    snapshot_due_ = true;
  }
  summary_.records_ms += MillisecondsSince(start);

  snapshot_due_ = snapshot_due_ || final;
  if (!snapshot_due_ || (!final && engine_ms_since_snapshot_ * options_.max_snapshot_share <
                                       summary_.last_snapshot_ms)) {
    return;
  }
  start = std::chrono::steady_clock::now();
  const std::size_t bytes = WriteBinary(dir_ / "snapshot.bin",
                                        [&](std::ostream& out) { engine.WriteSnapshot(out); });
  summary_.last_snapshot_ms = MillisecondsSince(start);
  summary_.last_snapshot_bytes = bytes;
  summary_.snapshots_ms += summary_.last_snapshot_ms;
  summary_.bytes += bytes;
  ++summary_.num_snapshots;
  engine_ms_since_snapshot_ = 0;
  snapshot_due_ = false;
  // Older retrieval models are named by no snapshot any more.
  for (const auto& entry : std::filesystem::directory_iterator(dir_ / "retrieval")) {
    if (entry.path() != ImageFile("retrieval", image_t(model_version))) {
      std::error_code ignored;
      std::filesystem::remove(entry.path(), ignored);
    }
  }
}

}  // namespace flysfm
