#include "io/sources/quarantine.h"

#include <poll.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <fstream>
#include <functional>
#include <thread>

#include <catch2/catch.hpp>

#include "tests/testing/process.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

TEST_CASE("A journal keeps any field whole and drops a line cut short") {
  const fs::path path = testing::MakeTempDir("journal") / "journal.tsv";
  const std::vector<std::string> odd = {"a\tb", "line\nbreak", "back\\slash", ""};
  {
    JournalFile journal(path);
    journal.Append(odd);
    journal.Append({"second"});
  }
  std::ofstream(path, std::ios::app) << "cut\tshort";
  const std::vector<std::vector<std::string>> records = JournalFile::Read(path);
  REQUIRE(records.size() == 2);
  CHECK(records[0] == odd);
  CHECK(records[1] == std::vector<std::string>{"second"});
  CHECK(JournalFile::Read(path.parent_path() / "none.tsv").empty());
}

void AppendRecords(const fs::path& path,
                   const std::vector<std::pair<std::string, std::string>>& records) {
  JournalFile journal(path);
  for (const auto& [kind, name] : records) journal.Append({kind, name});
}

// How many records of `path` are {kind, name}.
std::size_t Count(const fs::path& path, const std::string& kind, const std::string& name) {
  std::size_t count = 0;
  for (const std::vector<std::string>& record : JournalFile::Read(path)) {
    count += record.size() >= 2 && record[0] == kind && record[1] == name;
  }
  return count;
}

TEST_CASE("Deaths without a crash report never quarantine, however many in a row") {
  const fs::path path = testing::MakeTempDir("quarantine_killed") / "quarantine.tsv";
  AppendRecords(path, {{"decode", "a.jpg"}, {"engine", "a.jpg"}, {"done", "a.jpg"}});
  for (int death = 1; death <= 5; ++death) {
    // What a run leaves when it dies without a report (SIGKILL, the OOM
    // killer, a power cut) in the engine on b.jpg while c.jpg is decoded
    // ahead.
    AppendRecords(path, {{"decode", "b.jpg"}, {"engine", "b.jpg"}, {"decode", "c.jpg"}});
    const Quarantine quarantine(path, /*retry=*/false);
    CHECK_FALSE(quarantine.Reason("a.jpg"));
    CHECK_FALSE(quarantine.Reason("b.jpg"));
    CHECK_FALSE(quarantine.Reason("c.jpg"));
    // Recorded, for the record.
    CHECK(Count(path, "killed", "b.jpg") == std::size_t(death));
    CHECK(Count(path, "killed", "c.jpg") == std::size_t(death));
  }
  // A start that dies before it reaches b.jpg again does not record its
  // death against b.jpg.
  { const Quarantine quarantine(path, /*retry=*/false); }
  CHECK(Count(path, "killed", "b.jpg") == 5);
  CHECK(Count(path, "poison", "b.jpg") == 0);
  // Dying while decoding, with nothing in the engine, is no evidence either.
  for (int death = 0; death < 3; ++death) {
    AppendRecords(path, {{"decode", "d.jpg"}});
    CHECK_FALSE(Quarantine(path, /*retry=*/false).Reason("d.jpg"));
  }
  CHECK(Count(path, "killed", "d.jpg") == 3);
}

TEST_CASE("A crash report quarantines its image at once, the others open are innocent") {
  const fs::path path = testing::MakeTempDir("quarantine_crash") / "quarantine.tsv";
  AppendRecords(path, {{"decode", "a.jpg"}, {"engine", "a.jpg"}, {"decode", "b.jpg"},
                       {"crashed", "a.jpg"}});
  {
    Quarantine quarantine(path, /*retry=*/false);
    CHECK(quarantine.Reason("a.jpg") == std::optional<std::string>("the process crashed on it"));
    CHECK_FALSE(quarantine.Reason("b.jpg"));
    // Left open when the run ends normally: not blamed at the next start.
    quarantine.BeginDecode("e.jpg");
  }
  const Quarantine quarantine(path, /*retry=*/false);
  CHECK(quarantine.Reason("a.jpg"));
  CHECK_FALSE(quarantine.Reason("b.jpg"));
  CHECK_FALSE(quarantine.Reason("e.jpg"));
  CHECK(Count(path, "killed", "b.jpg") == 0);
  CHECK(Count(path, "killed", "e.jpg") == 0);
}

TEST_CASE("An engine exception quarantines its image, in this run and the next") {
  const fs::path path = testing::MakeTempDir("quarantine_failed") / "quarantine.tsv";
  {
    Quarantine quarantine(path, /*retry=*/false);
    quarantine.BeginDecode("d.jpg");
    quarantine.BeginEngine("d.jpg");
    quarantine.Fail("d.jpg", "engine error: boom");
    CHECK(quarantine.Reason("d.jpg") == std::optional<std::string>("engine error: boom"));
  }
  CHECK(Quarantine(path, /*retry=*/false).Reason("d.jpg") ==
        std::optional<std::string>("engine error: boom"));
}

TEST_CASE("A failed record appended by hand sets its image aside") {
  const fs::path path = testing::MakeTempDir("quarantine_by_hand") / "quarantine.tsv";
  AppendRecords(path, {{"engine", "hang.jpg"}, {"killed", "hang.jpg"}});
  // As docs/live.md gives it: printf 'failed\t%s\tset aside by hand\n' NAME.
  std::ofstream(path, std::ios::app) << "failed\thang.jpg\tset aside by hand\n";
  CHECK(Quarantine(path, /*retry=*/false).Reason("hang.jpg") ==
        std::optional<std::string>("set aside by hand"));
}

TEST_CASE("A poison record of an earlier version is honoured until a retry") {
  const fs::path path = testing::MakeTempDir("quarantine_poison") / "quarantine.tsv";
  {
    JournalFile journal(path);
    journal.Append({"decode", "p.jpg"});
    journal.Append({"engine", "p.jpg"});
    journal.Append({"killed", "p.jpg"});
    journal.Append({"decode", "p.jpg"});
    journal.Append({"engine", "p.jpg"});
    journal.Append({"killed", "p.jpg"});
    journal.Append({"poison", "p.jpg", "the process died on it 2 times in a row"});
  }
  for (int start = 0; start < 2; ++start) {
    const Quarantine quarantine(path, /*retry=*/false);
    REQUIRE(quarantine.Reason("p.jpg"));
    CHECK_THAT(*quarantine.Reason("p.jpg"), Catch::Contains("2 times in a row") &&
                                                Catch::Contains("earlier flysfm"));
  }
  CHECK_FALSE(Quarantine(path, /*retry=*/true).Reason("p.jpg"));
  CHECK_FALSE(Quarantine(path, /*retry=*/false).Reason("p.jpg"));
}

TEST_CASE("A retry gives every quarantined image another try, once") {
  const fs::path path = testing::MakeTempDir("quarantine_retry") / "quarantine.tsv";
  AppendRecords(path, {{"engine", "a.jpg"}, {"crashed", "a.jpg"}, {"failed", "b.jpg"}});
  {
    const Quarantine quarantine(path, /*retry=*/false);
    CHECK(quarantine.Reason("a.jpg"));
    CHECK(quarantine.Reason("b.jpg"));
  }
  {
    const Quarantine quarantine(path, /*retry=*/true);
    CHECK_FALSE(quarantine.Reason("a.jpg"));
    CHECK_FALSE(quarantine.Reason("b.jpg"));
  }
  CHECK(Count(path, "retry", "a.jpg") == 1);
  CHECK(Count(path, "retry", "b.jpg") == 1);
  // The retry holds at the next start without the flag, until new evidence.
  CHECK_FALSE(Quarantine(path, /*retry=*/false).Reason("a.jpg"));
  AppendRecords(path, {{"engine", "a.jpg"}, {"crashed", "a.jpg"}});
  CHECK(Quarantine(path, /*retry=*/false).Reason("a.jpg"));
}

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
// A sanitizer's own handler reports the fault and exits with a code.
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif

// Whether an exit code of testing::WaitForExit says the process died of
// `signal`.
bool DiedOf(int code, int signal) {
  return kSanitized ? code > 0 : code == 128 + signal;
}

// Runs `body` in a child process (fork: the test process has no other
// thread here) that never returns into Catch2, and returns its exit code as
// testing::WaitForExit gives it (-1 when it had to be killed after 10 s).
// `body` calls `ready` once the parent may act on it: `when_ready` then
// runs in the parent.
int RunChild(const std::function<void(const std::function<void()>& ready)>& body,
             const std::function<void(pid_t)>& when_ready = {}) {
  int pipe_fds[2];
  REQUIRE(::pipe(pipe_fds) == 0);
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    ::close(pipe_fds[0]);
    // No core file for a crash on purpose, and the default actions under
    // the quarantine's handler, as in the program (not Catch2's report).
    const rlimit no_core = {0, 0};
    ::setrlimit(RLIMIT_CORE, &no_core);
    for (const int signal : {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT}) {
      ::signal(signal, SIG_DFL);
    }
    try {
      body([&] { (void)!::write(pipe_fds[1], "r", 1); });
    } catch (...) {
      ::_exit(2);
    }
    ::_exit(0);
  }
  ::close(pipe_fds[1]);
  if (when_ready) {
    pollfd ready = {pipe_fds[0], POLLIN, 0};
    char byte = 0;
    const bool is_ready = ::poll(&ready, 1, 10000) == 1 && ::read(pipe_fds[0], &byte, 1) == 1;
    CHECK(is_ready);
    if (is_ready) when_ready(pid);
  }
  ::close(pipe_fds[0]);
  return testing::WaitForExit(pid, 10);
}

// A real fault (SIGSEGV, SEGV_ACCERR), not a signal sent.
void Fault() {
  void* page = ::mmap(nullptr, 4096, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  (void)*static_cast<volatile char*>(page);
}

volatile int never = -1;

// Recursion that fills any stack.
[[gnu::noinline]] int Overflow(int depth) {
  volatile char frame[4096];
  frame[0] = char(depth);
  if (depth == never) return 0;
  return Overflow(depth + 1) + frame[0];
}

TEST_CASE("A fault on the decode thread reports its image, not the one in the engine") {
  const fs::path path = testing::MakeTempDir("quarantine_fault") / "quarantine.tsv";
  const int code = RunChild([&](const std::function<void()>&) {
    Quarantine quarantine(path, /*retry=*/false);
    quarantine.BeginDecode("engine.jpg");
    quarantine.BeginEngine("engine.jpg");
    std::thread decode([&] {
      quarantine.BeginDecode("bad.jpg");
      Fault();
    });
    decode.join();
  });
  CHECK(DiedOf(code, SIGSEGV));
  CHECK(Count(path, "crashed", "bad.jpg") == 1);
  CHECK(Count(path, "crashed", "engine.jpg") == 0);
  const Quarantine quarantine(path, /*retry=*/false);
  CHECK(quarantine.Reason("bad.jpg"));
  CHECK_FALSE(quarantine.Reason("engine.jpg"));
}

TEST_CASE("A stack overflow on an image is reported as a crash") {
  const fs::path path = testing::MakeTempDir("quarantine_overflow") / "quarantine.tsv";
  const int code = RunChild([&](const std::function<void()>&) {
    Quarantine quarantine(path, /*retry=*/false);
    std::thread engine([&] {
      quarantine.BeginEngine("deep.jpg");
      Overflow(0);
    });
    engine.join();
  });
  CHECK(DiedOf(code, SIGSEGV));
  CHECK(Count(path, "crashed", "deep.jpg") == 1);
  CHECK(Quarantine(path, /*retry=*/false).Reason("deep.jpg"));
}

TEST_CASE("A fatal signal sent by another process is no crash report") {
  for (const int signal : {SIGSEGV, SIGABRT}) {
    const fs::path path = testing::MakeTempDir("quarantine_sent") / "quarantine.tsv";
    const int code = RunChild(
        [&](const std::function<void()>& ready) {
          Quarantine quarantine(path, /*retry=*/false);
          quarantine.BeginDecode("good.jpg");
          quarantine.BeginEngine("good.jpg");
          ready();
          // Long enough for the parent's wait to give up if the signal
          // were swallowed; interrupted sleeps end early, hence the count.
          for (int i = 0; i < 200; ++i) ::usleep(100000);
        },
        [&](pid_t pid) { ::kill(pid, signal); });
    CHECK(DiedOf(code, signal));
    CHECK(Count(path, "crashed", "good.jpg") == 0);
    // It died in the engine on good.jpg all the same: killed, not set aside.
    const Quarantine quarantine(path, /*retry=*/false);
    CHECK_FALSE(quarantine.Reason("good.jpg"));
    CHECK(Count(path, "killed", "good.jpg") == 1);
  }
}

TEST_CASE("The filter hands on all but the quarantined frames") {
  const fs::path path = testing::MakeTempDir("quarantine_filter") / "quarantine.tsv";
  std::vector<Frame> frames(3);
  for (int i = 0; i < 3; ++i) frames[std::size_t(i)].name = "f" + std::to_string(i);
  Quarantine quarantine(path, /*retry=*/false);
  quarantine.Fail("f1", "engine error");
  FrameListSource source(frames);
  QuarantineFilterSource filtered(&source, &quarantine);
  std::vector<std::string> names;
  while (std::optional<Frame> frame = filtered.Next()) names.push_back(frame->name);
  CHECK(names == std::vector<std::string>{"f0", "f2"});
  CHECK(filtered.num_skipped() == 1);
}

}  // namespace
}  // namespace flysfm
