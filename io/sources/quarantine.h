#pragma once

// Images kept from the engine: a photo that crashes the engine would crash
// every restart too, with no way past it. OUT/quarantine.tsv (a JournalFile)
// records, each in the kernel before the step it announces begins:
//   decode NAME       the prefetch thread is about to decode NAME
//   engine NAME       the engine is about to take NAME
//   done NAME         NAME is through, whatever its result (or never started)
//   crashed NAME      a fatal signal (SIGSEGV, SIGBUS, SIGILL, SIGFPE,
//                     SIGABRT) of the process's own making (a fault,
//                     abort()) hit the thread working on NAME
//   failed NAME WHY   the engine threw an exception on NAME
//   killed NAME       the process died without a crash report during NAME
//                     (SIGKILL, the OOM killer, a power cut, a fatal signal
//                     sent by another process)
//   poison NAME WHY   written by earlier versions only: read as quarantined
//   retry NAME        NAME gets another try (--retry-quarantined)
// Only evidence that the engine failed on an image quarantines it: `crashed`
// or `failed` (and an old `poison`). A death without a report cannot tell a
// hostile photo from a user's `kill -9`, the OOM killer or a power cut, and a
// good photo set aside is lost for good, so `killed` never quarantines: the
// image is processed again at every start. docs/live.md says what bounds a
// photo that hangs the engine or exhausts memory instead.

#include <atomic>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <unordered_set>
#include <vector>

#include "io/sources/image_source.h"
#include "io/sources/journal_file.h"

namespace flysfm {

class Quarantine {
 public:
  // Reads `file` (none: nothing quarantined), records `killed` for the
  // images the previous run died on without a report (on stderr too), and
  // installs the fatal-signal handler that records `crashed` (one Quarantine
  // per process at a time). With `retry`, every quarantined image gets another
  // try. Throws std::runtime_error when the file cannot be written.
  Quarantine(const std::filesystem::path& file, bool retry);
  // Restores the previous signal handlers and records `done` for the images
  // still open: the run ended without dying on them.
  ~Quarantine();
  Quarantine(const Quarantine&) = delete;
  Quarantine& operator=(const Quarantine&) = delete;

  // Why `name` is quarantined; nullopt when it is not. Thread-safe, as are
  // the records below. BeginDecode and BeginEngine also make `name` the
  // calling thread's image for the signal handler, and give that thread an
  // alternate signal stack if it has none (a stack overflow is a crash to
  // report too); Done and Fail make it no image's.
  std::optional<std::string> Reason(const std::string& name) const;
  void BeginDecode(const std::string& name);
  void BeginEngine(const std::string& name);
  void Done(const std::string& name);
  void Fail(const std::string& name, const std::string& why);

 private:
  void Append(const std::vector<std::string>& fields);
  void Begin(const std::string& step, const std::string& name);

  JournalFile journal_;
  mutable std::mutex mutex_;
  std::map<std::string, std::string> reasons_;
  std::set<std::string> open_;
};

// Hands on the frames of `source` but the quarantined ones (reported on
// stderr and counted) and those named in `in_model` (images a resumed model
// holds already, counted), recording `decode` for each frame handed on: the
// source the prefetch thread reads.
class QuarantineFilterSource : public ImageSource {
 public:
  // All must outlive this object.
  QuarantineFilterSource(ImageSource* source, Quarantine* quarantine,
                         const std::unordered_set<std::string>* in_model = nullptr);
  std::optional<Frame> Next() override;
  void Stop() override { source_->Stop(); }

  int num_skipped() const { return num_skipped_; }
  int num_in_model() const { return num_in_model_; }

 private:
  ImageSource* source_;
  Quarantine* quarantine_;
  const std::unordered_set<std::string>* in_model_;
  std::atomic<int> num_skipped_{0};
  std::atomic<int> num_in_model_{0};
};

}  // namespace flysfm
