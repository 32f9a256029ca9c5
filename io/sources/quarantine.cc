#include "io/sources/quarantine.h"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <iostream>

namespace flysfm {
namespace {

const int kFatalSignals[] = {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT};
struct sigaction previous_actions[std::size(kFatalSignals)];
std::atomic<int> crash_fd{-1};
// The `crashed` line for this thread's current image, ready for the handler
// (which may not allocate); empty when the thread is on no image or the
// name does not fit. Plain arrays and a volatile size: no lazy
// initialisation in the handler, and no store the compiler may move past
// the handler's read.
thread_local char crash_line[4096];
thread_local volatile std::sig_atomic_t crash_line_size = 0;

void RecordCrash(int signal, siginfo_t* info, void*) {
  const int saved_errno = errno;
  // A fatal signal another process sent (`kill -SEGV`, a supervisor's
  // SIGABRT on a timeout) says nothing about the image: a death like
  // SIGKILL. abort() and raise() send from this process.
  const bool sent = info->si_code <= 0;
  const bool from_outside = sent && info->si_pid != ::getpid();
  const int fd = crash_fd.load();
  if (!from_outside && fd >= 0 && crash_line_size > 0) {
    (void)!::write(fd, crash_line, std::size_t(crash_line_size));
  }
  // The handler before this one (the default, or a sanitizer's report) takes
  // over: a fault happens again on return; a sent signal, blocked while this
  // handler runs, is sent again and arrives on return.
  for (std::size_t i = 0; i < std::size(kFatalSignals); ++i) {
    if (kFatalSignals[i] == signal) ::sigaction(signal, &previous_actions[i], nullptr);
  }
  if (sent) ::raise(signal);
  errno = saved_errno;
}

void ClearCrashLine() { crash_line_size = 0; }

void SetCrashLine(const std::string& name) {
  ClearCrashLine();
  const std::string line = JournalFile::Line({"crashed", name});
  if (line.size() > sizeof(crash_line)) return;
  std::memcpy(crash_line, line.data(), line.size());
  // The line is whole before the handler may see its size.
  std::atomic_signal_fence(std::memory_order_release);
  crash_line_size = std::sig_atomic_t(line.size());
}

// A stack overflow faults with no stack left for a handler: without a stack
// of its own, the handler cannot record it, and the photo that overflows
// would be retried at every start. Installed once per thread that works on
// images, unless the thread has one already (a sanitizer's).
class AltStack {
 public:
  void EnsureInstalled() {
    if (installed_ || declined_) return;
    stack_t current = {};
    if (::sigaltstack(nullptr, &current) != 0 || !(current.ss_flags & SS_DISABLE)) {
      declined_ = true;
      return;
    }
    memory_.resize(std::max<std::size_t>(std::size_t(SIGSTKSZ), 64 * 1024));
    stack_t stack = {};
    stack.ss_sp = memory_.data();
    stack.ss_size = memory_.size();
    installed_ = ::sigaltstack(&stack, nullptr) == 0;
    declined_ = !installed_;
  }
  ~AltStack() {
    if (!installed_) return;
    stack_t off = {};
    off.ss_flags = SS_DISABLE;
    ::sigaltstack(&off, nullptr);
  }

 private:
  std::vector<char> memory_;
  bool installed_ = false;
  bool declined_ = false;
};
thread_local AltStack alt_stack;

}  // namespace

Quarantine::Quarantine(const std::filesystem::path& file, bool retry) : journal_(file) {
  // The step each image was last seen in while not through, and its deaths
  // without a report since it last went through (for the message only).
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
      // Closed: a death before the image is reached again is not its own.
      open.erase(name);
      ++deaths[name];
    } else if (kind == "failed") {
      open.erase(name);
      reasons_[name] = record.size() > 2 ? record[2] : kind;
    } else if (kind == "poison") {
      // Set aside by an earlier version after deaths without a report: kept
      // until --retry-quarantined, so that an output folder reads the same.
      open.erase(name);
      reasons_[name] = (record.size() > 2 ? record[2] : kind) +
                       "; set aside by an earlier flysfm without a crash report";
    } else if (kind == "retry") {
      reasons_.erase(name);
    }
  }
  for (const auto& [name, step] : open) {
    Append({"killed", name});
    const int count = ++deaths[name];
    std::cerr << "quarantine: the previous run died without a crash report while "
              << (step == "engine" ? "the engine was on " : "decoding ") << name
              << "; it is processed again";
    if (count > 1) {
      std::cerr << " (" << count << " such deaths on it in a row: to set it aside by hand, "
                << "docs/live.md, \"Quarantine\")";
    }
    std::cerr << "\n";
  }
  if (retry) {
    for (const auto& [name, why] : reasons_) Append({"retry", name});
    reasons_.clear();
  }
  crash_fd = journal_.fd();
  struct sigaction action = {};
  action.sa_sigaction = RecordCrash;
  action.sa_flags = SA_SIGINFO | SA_ONSTACK;
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
  alt_stack.EnsureInstalled();
  std::lock_guard<std::mutex> lock(mutex_);
  SetCrashLine(name);
  Append({step, name});
}

void Quarantine::BeginDecode(const std::string& name) { Begin("decode", name); }

void Quarantine::BeginEngine(const std::string& name) { Begin("engine", name); }

void Quarantine::Done(const std::string& name) {
  std::lock_guard<std::mutex> lock(mutex_);
  ClearCrashLine();
  Append({"done", name});
}

void Quarantine::Fail(const std::string& name, const std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  ClearCrashLine();
  Append({"failed", name, why});
  reasons_[name] = why;
}

QuarantineFilterSource::QuarantineFilterSource(ImageSource* source, Quarantine* quarantine,
                                               const std::unordered_set<std::string>* in_model)
    : source_(source), quarantine_(quarantine), in_model_(in_model) {}

std::optional<Frame> QuarantineFilterSource::Next() {
  // The thread asking for the next frame is through with the one before: a
  // crash while it waits for the source is no image's.
  ClearCrashLine();
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
