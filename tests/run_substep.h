// For the tests that run the built `substep` binary (test_cli, test_render_cli, test_snapshot_cli):
// one call, its exit status and everything it printed, a scratch folder per test, and what a
// folder holds.
#pragma once

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace substep_test {

struct Outcome {
  int status;
  std::string output;  // stdout and stderr
};

// Runs a shell command line from the source folder, stdout and stderr together.
inline Outcome runShell(const std::string& command) {
  const std::string cmd = "cd " SUBSTEP_SOURCE_DIR " && " + command + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  Outcome r{-1, ""};
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
  const int st = pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

// Runs `substep ARGS` from the source folder, with `env` (VAR=value ...) in front.
inline Outcome runSubstep(const std::string& args, const std::string& env = "") {
  return runShell(env + " " SUBSTEP_EXE " " + args);
}

// Runs `substep ARGS` with stderr a terminal (a pseudo-terminal from script(1)), as a person
// at a shell would: the progress bar shows only then.
inline Outcome runSubstepOnTerminal(const std::string& args) {
  // The bar from the start: a quick machine finishes some jobs within the usual first second.
  return runShell("SUBSTEP_PROGRESS_DELAY=0 script -qec '" SUBSTEP_EXE " " + args + "' /dev/null");
}

// <build>/<suite>/<test name>/: CTest runs tests in parallel, and some look at what is in theirs.
inline std::filesystem::path scratchFolder(const std::string& suite) {
  return std::filesystem::path(SUBSTEP_BINARY_DIR) / suite /
         ::testing::UnitTest::GetInstance()->current_test_info()->name();
}

// The same, emptied: for tests that look at everything in it.
inline std::filesystem::path emptyScratchFolder(const std::string& suite) {
  const std::filesystem::path d = scratchFolder(suite);
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

// The names in a folder, sorted; none if it does not exist.
inline std::vector<std::string> listing(const std::filesystem::path& d) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(d, ec)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

}  // namespace substep_test
