#pragma once

// Runs the built `flysfm` program (FLYSFM_BINARY, set by CMake) as a child
// process, its output in a file, so that a test can signal or kill it.

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "tests/testing/process.h"

namespace flysfm::testing {

inline pid_t SpawnFlysfm(const std::vector<std::string>& args,
                         const std::filesystem::path& output) {
  std::vector<std::string> argv_strings = {FLYSFM_BINARY};
  argv_strings.insert(argv_strings.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& arg : argv_strings) argv.push_back(arg.data());
  argv.push_back(nullptr);
  const std::string output_path = output.string();
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fd = ::open(output_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  return pid;
}

}  // namespace flysfm::testing
