#include "io/run/progress_line.h"

#include <pty.h>
#include <unistd.h>

#include <cstdio>
#include <regex>
#include <string>
#include <thread>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

// What `write` prints into a temporary file that is not a terminal.
std::string PrintedPlain(const std::function<void(std::FILE*)>& write) {
  std::FILE* file = std::tmpfile();
  REQUIRE(file != nullptr);
  write(file);
  std::fflush(file);
  std::rewind(file);
  std::string text;
  for (int c; (c = std::fgetc(file)) != EOF;) text += char(c);
  std::fclose(file);
  return text;
}

// Every line a script reads off a plain progress output.
const std::regex kPlainLine(
    R"(end: [a-z ]+(, [a-z0-9 ,]+)?; [0-9]+\.[0-9] s(, at most [0-9]+ s left)?)");

TEST_CASE("Plain progress: a line per step, repeated only after the interval, each parseable") {
  const std::string text = PrintedPlain([](std::FILE* out) {
    ProgressLine line(out, /*plain_interval_s=*/60);
    line.Show("global adjustment", "iteration 1 of at most 50", 0.5, 7.0);
    line.Show("global adjustment", "iteration 2 of at most 50", 1.0, 6.4);  // within the interval
    line.Show("data snooping", "adjustment 1 of at most 10, iteration 0 of at most 50", 1.5);
    line.Done();
    line.Show("writing the final model and checkpoint", "", 2.25);
  });
  CHECK(text ==
        "end: global adjustment, iteration 1 of at most 50; 0.5 s, at most 7 s left\n"
        "end: data snooping, adjustment 1 of at most 10, iteration 0 of at most 50; 1.5 s\n"
        "end: writing the final model and checkpoint; 2.2 s\n");
  std::size_t begin = 0;
  for (std::size_t end; (end = text.find('\n', begin)) != std::string::npos; begin = end + 1) {
    const std::string line = text.substr(begin, end - begin);
    INFO(line);
    CHECK(std::regex_match(line, kPlainLine));
  }
  CHECK(text.find('\r') == std::string::npos);
}

TEST_CASE("Plain progress repeats a step once its interval passed") {
  const std::string text = PrintedPlain([](std::FILE* out) {
    ProgressLine line(out, /*plain_interval_s=*/0.05);
    line.Show("global adjustment", "iteration 1 of at most 50", 0.1);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    line.Show("global adjustment", "iteration 2 of at most 50", 0.2);
  });
  CHECK(text ==
        "end: global adjustment, iteration 1 of at most 50; 0.1 s\n"
        "end: global adjustment, iteration 2 of at most 50; 0.2 s\n");
}

TEST_CASE("On a terminal the line is rewritten in place and ended by Done") {
  int master = -1, slave = -1;
  REQUIRE(::openpty(&master, &slave, nullptr, nullptr, nullptr) == 0);
  std::FILE* terminal = ::fdopen(slave, "w");
  REQUIRE(terminal != nullptr);
  {
    ProgressLine line(terminal);
    line.Show("global adjustment", "iteration 1 of at most 50", 0.5);
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
    line.Show("global adjustment", "iteration 2 of at most 50", 0.9);
    line.Done();
  }
  std::fclose(terminal);
  std::string text;
  char buffer[4096];
  for (ssize_t n; (n = ::read(master, buffer, sizeof(buffer))) > 0;) {
    text.append(buffer, std::size_t(n));
    if (text.find("0.9 s") != std::string::npos && text.back() == '\n') break;
  }
  ::close(master);
  // The terminal turns "\n" into "\r\n".
  CHECK(text ==
        "\rend: global adjustment, iteration 1 of at most 50; 0.5 s\033[K"
        "\rend: global adjustment, iteration 2 of at most 50; 0.9 s\033[K\r\n");
}

}  // namespace
}  // namespace flysfm
