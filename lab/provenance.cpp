#include "lab/provenance.h"

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <fstream>

#ifndef SUBSTEP_SOURCE_DIR
#define SUBSTEP_SOURCE_DIR "."
#endif

namespace substep::lab {

namespace {

// A command's standard output, or "" when it fails.
std::string output(const std::string& cmd) {
  std::string out;
  if (FILE* p = popen((cmd + " 2>/dev/null").c_str(), "r")) {
    char buf[256];
    while (std::fgets(buf, sizeof buf, p)) out += buf;
    if (pclose(p) != 0) return std::string();
  }
  return out;
}

std::string git() { return std::string("git -C '") + SUBSTEP_SOURCE_DIR + "' "; }

}  // namespace

std::string sourceCommit() {
  // Once per process: a sweep asks for every row.
  static const std::string commit = [] {
    std::string c = output(git() + "rev-parse --short HEAD");
    c.erase(c.find_last_not_of("\n") + 1);
    return c.empty() ? std::string("unknown") : c;
  }();
  return commit;
}

std::string sourceState() {
  const std::string commit = sourceCommit();
  if (commit == "unknown") return commit;
  const std::string changed = output(git() + "status --porcelain -- physics");
  const long files = std::count(changed.begin(), changed.end(), '\n');
  return commit + (files ? " + uncommitted changes in " + std::to_string(files) + " file(s) under physics/" : "");
}

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      if (colon != std::string::npos) return line.substr(line.find_first_not_of(' ', colon + 1));
    }
  return "unknown CPU";
}

std::string loadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  if (!(in >> a >> b >> c)) return "unknown";
  return a + " " + b + " " + c;
}

std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

}  // namespace substep::lab
