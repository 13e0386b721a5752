#include "app/chart_files.h"

#include "app/common.h"
#include "render/video.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

extern char** environ;

namespace substep::app {

namespace {

namespace fs = std::filesystem;

// gnuplot on a script; its messages go to `log`. Returns the exit status (-1: not started).
int runGnuplot(const std::string& gnuplot, const std::string& script, const std::string& log) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  std::vector<std::string> args = {gnuplot, script};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, gnuplot.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) return -1;
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

void writeText(const std::string& path, const std::string& text) {
  AtomicFile f(path);
  f.out() << text;
  f.commit();
}

}  // namespace

std::string findGnuplot() {
  if (const char* env = std::getenv("SUBSTEP_GNUPLOT"); env && *env) return render::findProgram(env);
  return render::findProgram("gnuplot");
}

std::vector<std::string> writeCharts(const std::vector<nlohmann::json>& rows, const lab::ChartOptions& options,
                                     const std::string& folder, bool quiet) {
  const std::string gnuplot = findGnuplot();
  if (gnuplot.empty())
    throw UsageError(std::string("charts are drawn by gnuplot, which is not ") +
                     (std::getenv("SUBSTEP_GNUPLOT") ? "at $SUBSTEP_GNUPLOT" : "on PATH") + " (Debian: apt-get install gnuplot-nox)");
  const fs::path dir = fs::path(folder);
  const fs::path data = dir / "data";
  checkWritable((data / "charts.gp").string(), "-o " + folder);
  const std::vector<lab::Chart> charts = lab::makeCharts(rows, options);
  // One gnuplot run draws every chart into temporary names; the kept scripts name the final ones,
  // relative to the folder, so that `cd DIR && gnuplot data/NAME.gp` redraws a chart.
  const std::string tag = ".part" + std::to_string(getpid());
  std::string run;
  std::vector<std::pair<std::string, std::string>> outputs;  // temporary, final
  for (const lab::Chart& c : charts) {
    const std::string dat = (data / (c.name + ".dat")).string();
    writeText(dat, c.data);
    std::string kept;
    for (const char* term : {"png", "svg"}) {
      const std::string file = c.name + "." + term;
      kept += lab::chartScript(c, term, file, "data/" + c.name + ".dat", options) + "\nunset output\nreset\n";
      const std::string final = (dir / file).string();
      run += lab::chartScript(c, term, final + tag, dat, options) + "\nunset output\nreset\n";
      outputs.emplace_back(final + tag, final);
    }
    writeText((data / (c.name + ".gp")).string(), kept);
  }
  const std::string script = (data / ("run" + tag + ".gp")).string(), log = (data / ("gnuplot" + tag + ".log")).string();
  writeText(script, run);
  const int status = runGnuplot(gnuplot, script, log);
  std::ifstream logIn(log);
  std::stringstream messages;
  messages << logIn.rdbuf();
  std::error_code ec;
  fs::remove(script, ec);
  fs::remove(log, ec);
  if (status != 0) {
    for (const auto& [temp, final] : outputs) fs::remove(temp, ec);
    throw std::runtime_error("gnuplot failed (status " + std::to_string(status) + "): " + messages.str());
  }
  std::vector<std::string> written;
  for (const auto& [temp, final] : outputs) {
    if (!fs::exists(temp) || fs::file_size(temp) == 0)
      throw std::runtime_error("gnuplot wrote no " + final + ": " + messages.str());
    fs::rename(temp, final);
    written.push_back(final);
  }
  if (!quiet)
    for (const lab::Chart& c : charts) {
      std::cout << "chart     " << (dir / (c.name + ".png")).string() << "  " << c.title << "\n";
      for (const std::string& n : c.notes) std::cout << "            " << n << "\n";
    }
  return written;
}

}  // namespace substep::app
