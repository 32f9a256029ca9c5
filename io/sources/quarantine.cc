#include "io/sources/quarantine.h"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <iostream>

namespace flysfm {
namespace {

const int kFatalSignals[] = {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT};
struct sigaction previous_actions[std::size(kFatalSignals)];
std::atomic<int> crash_fd{-1};
// The `crashed` line for this thread's current image, ready for the handler
// (which may not allocate); empty when the thread is on no image or the
// name does not fit. Plain arrays: no lazy initialisation in the handler.
thread_local char crash_line[1024];
thread_local std::size_t crash_line_size = 0;

void RecordCrash(int signal) {
  const int saved_errno = errno;
  const int fd = crash_fd.load();
  if (fd >= 0 && crash_line_size > 0) (void)!::write(fd, crash_line, crash_line_size);
  // The handler before this one (the default, or a sanitizer's report) takes
  // over: a fault happens again on return, and abort() raises again.
  for (std::size_t i = 0; i < std::size(kFatalSignals); ++i) {
    if (kFatalSignals[i] == signal) ::sigaction(signal, &previous_actions[i], nullptr);
  }
  errno = saved_errno;
}

void SetCrashLine(const std::string& name) {
  const std::string line = JournalFile::Line({"crashed", name});
  crash_line_size = 0;
  if (line.size() <= sizeof(crash_line)) {
    std::memcpy(crash_line, line.data(), line.size());
    crash_line_size = line.size();
  }
}

}  // namespace

Quarantine::Quarantine(const std::filesystem::path& file, bool retry) : journal_(file) {
  // The step each image was last seen in while not through, and its deaths
  // without a report since it last went through.
  std::map<std::string, std::string> open;
  std::map<std::string, int> deaths;
  for (const std::vector<std::string>& record : JournalFile::Read(file)) {
    if (record.size() < 2) continue;
    const std::string& kind = record[0];
    const std::string& name = record[1];
    if (kind == "decode" || kind == "engine") {
      open[name] = kind;
    } else if (kind == "done") {
      open.erase(name);
      deaths.erase(name);
    } else if (kind == "crashed") {
      reasons_[name] = "the process crashed on it";
      // The run ended there: the other open images were innocent.
      open.clear();
    } else if (kind == "killed") {
      ++deaths[name];
    } else if (kind == "failed" || kind == "poison") {
      open.erase(name);
      reasons_[name] = record.size() > 2 ? record[2] : kind;
    } else if (kind == "retry") {
      reasons_.erase(name);
      deaths.erase(name);
    }
  }
  bool engine_open = false;
  for (const auto& [name, step] : open) engine_open |= step == "engine";
  for (const auto& [name, step] : open) {
    if (step == "decode" && engine_open) {
      Append({"done", name});
      continue;
    }
    Append({"killed", name});
    if (++deaths[name] < kDeathsToQuarantine) {
      std::cerr << "quarantine: the previous run died while on " << name
                << "; it gets one more try\n";
      continue;
    }
    const std::string why = "the process died on it " + std::to_string(deaths[name]) +
                            " times in a row";
    Append({"poison", name, why});
    reasons_[name] = why;
    std::cerr << "quarantine: " << name << ": " << why << "; it is quarantined\n";
  }
  if (retry) {
    for (const auto& [name, why] : reasons_) Append({"retry", name});
    reasons_.clear();
  }
  crash_fd = journal_.fd();
  struct sigaction action = {};
  action.sa_handler = RecordCrash;
  sigemptyset(&action.sa_mask);
  for (std::size_t i = 0; i < std::size(kFatalSignals); ++i) {
    ::sigaction(kFatalSignals[i], &action, &previous_actions[i]);
  }
}

Quarantine::~Quarantine() {
  for (std::size_t i = 0; i < std::size(kFatalSignals); ++i) {
    ::sigaction(kFatalSignals[i], &previous_actions[i], nullptr);
  }
  crash_fd = -1;
  try {
    for (const std::string& name : std::set<std::string>(open_)) Done(name);
  } catch (const std::exception& e) {
    std::cerr << "quarantine: " << e.what() << "\n";
  }
}

void Quarantine::Append(const std::vector<std::string>& fields) {
  journal_.Append(fields);
  if (fields[0] == "decode" || fields[0] == "engine") {
    open_.insert(fields[1]);
  } else {
    open_.erase(fields[1]);
  }
}

std::optional<std::string> Quarantine::Reason(const std::string& name) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto found = reasons_.find(name);
  if (found == reasons_.end()) return std::nullopt;
  return found->second;
}

void Quarantine::Begin(const std::string& step, const std::string& name) {
  std::lock_guard<std::mutex> lock(mutex_);
  SetCrashLine(name);
  Append({step, name});
}

void Quarantine::BeginDecode(const std::string& name) { Begin("decode", name); }

void Quarantine::BeginEngine(const std::string& name) { Begin("engine", name); }

void Quarantine::Done(const std::string& name) {
  std::lock_guard<std::mutex> lock(mutex_);
  crash_line_size = 0;
  Append({"done", name});
}

void Quarantine::Fail(const std::string& name, const std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  crash_line_size = 0;
  Append({"failed", name, why});
  reasons_[name] = why;
}

QuarantineFilterSource::QuarantineFilterSource(ImageSource* source, Quarantine* quarantine,
                                               const std::unordered_set<std::string>* in_model)
    : source_(source), quarantine_(quarantine), in_model_(in_model) {}

std::optional<Frame> QuarantineFilterSource::Next() {
  while (std::optional<Frame> frame = source_->Next()) {
    if (in_model_ && in_model_->count(frame->name) > 0) {
      ++num_in_model_;
      continue;
    }
    if (const std::optional<std::string> why = quarantine_->Reason(frame->name)) {
      std::cerr << "quarantine: skipping " << frame->name << " (" << *why
                << "); --retry-quarantined gives it another try\n";
      ++num_skipped_;
      continue;
    }
    quarantine_->BeginDecode(frame->name);
    return frame;
  }
  return std::nullopt;
}

}  // namespace flysfm
