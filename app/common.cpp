#include "app/common.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cstdlib>
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <thread>

#ifndef SUBSTEP_SOURCE_DIR
#define SUBSTEP_SOURCE_DIR "."
#endif
#ifndef SUBSTEP_INSTALLED_ASSETS
#define SUBSTEP_INSTALLED_ASSETS "../share/substep/assets"
#endif

namespace substep::app {

namespace fs = std::filesystem;

void SolverOptions::add(CLI::App& cmd) {
  for (const SettingSpec& spec : settingTable()) {
    const std::string flag = std::string("--") + spec.flag;
    const std::string help = std::string(spec.help) + (spec.takes.all() ? "" : " [" + spec.takes.text() + "]") +
                             (spec.resolved() ? "; default " + defaultsText(spec) : "");
    if (spec.kind == SettingKind::Flag) {
      auto& f = flags[spec.key];
      cmd.add_flag(flag, f.first, help);
      cmd.add_flag("--no-" + std::string(spec.flag), f.second, std::string("Turn ") + flag + " off");
      continue;
    }
    cmd.add_option(flag, values[spec.key], help + (spec.kind == SettingKind::Choice ? "" : "; " + spec.expected()));
  }
}

SolverOverrides SolverOptions::overrides() const {
  SolverOverrides o;
  for (const SettingSpec& spec : settingTable()) {
    const std::string flag = std::string("--") + spec.flag;
    if (spec.kind == SettingKind::Flag) {
      const auto it = flags.find(spec.key);
      if (it == flags.end()) continue;
      const auto [on, off] = it->second;
      if (on && off) throw UsageError(flag + " and --no-" + spec.flag + " contradict each other");
      if (on || off) o.set(spec, on ? 1 : 0);
      continue;
    }
    const auto it = values.find(spec.key);
    if (it == values.end() || !it->second) continue;
    try {
      o.setText(spec, *it->second);
    } catch (const std::invalid_argument& e) {
      throw UsageError(flag + ": " + e.what());
    }
  }
  return o;
}

CLI::Validator finiteIn(double lo, double hi) {
  const Range r{lo, hi};
  return CLI::Validator(
      [r](std::string& s) -> std::string {
        char* end = nullptr;
        const double x = std::strtod(s.c_str(), &end);
        if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(x) || !r.contains(x))
          return "expected " + r.expected() + ", got \"" + s + "\"";
        return "";
      },
      r.expected());
}

SolverSettings resolveSettings(const Scene& scene, const SolverOverrides& cl) {
  try {
    return resolveFor(scene.solver, cl);
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    const SettingSpec* s = findSetting(what.substr(0, what.find(':')));
    // "--kappa: a2 does not use it (a3, a4, a5 do)": the option as it was typed.
    if (s && cl.has(*s)) throw UsageError("--" + std::string(s->flag) + what.substr(what.find(':')));
    throw UsageError("solver settings (" + scene.file + " or the command line): " + what);
  }
}

SolverOverrides onEveryCore(const Scene& scene, SolverOverrides given) {
  const SettingSpec& threads = settingOf(&SolverSettings::threads);
  if (scene.solver.has(threads) || given.has(threads)) return given;
  // Below a few thousand moving bodies handing the work out costs more than it saves: on 2
  // threads the 210-box pyramid stepped at 0.72x, the 820-box one at 0.81x, the 10 000-box pile
  // at 1.2-1.3x (docs/benchmarks.md, "Threads").
  const auto moving = std::count_if(scene.model.bodies.begin(), scene.model.bodies.end(), [](const Body& b) { return !b.isStatic; });
  if (moving < kEveryCoreFromBodies) return given;
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  given.set(threads, std::min<double>(cores, limits::kMaxThreads));
  return given;
}

Scene load(const std::string& path, const SceneLimits& lim) {
  try {
    return loadScene(path, lim);
  } catch (const SceneError& e) {
    throw UsageError(e.what());
  }
}

void addMaxBodies(CLI::App& cmd, SceneLimits& lim) {
  cmd.add_option("--max-bodies", lim.maxBodies,
                 "Refuse scenes with more bodies (or joints) than this (default " +
                     std::to_string(limits::kDefaultMaxBodies) + ")")
      ->check(CLI::Range(1LL, static_cast<long long>(limits::kMaxBodiesCeiling)));
}

std::string assetsDir() {
  if (const char* env = std::getenv("SUBSTEP_ASSETS")) return env;
  // An installed program: PREFIX/bin/substep beside PREFIX/share/substep/assets.
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = (exe.parent_path() / SUBSTEP_INSTALLED_ASSETS).lexically_normal();
    if (fs::is_directory(installed / "scenes", ec)) return installed.string();
  }
  return std::string(SUBSTEP_SOURCE_DIR) + "/assets";
}

std::string scenePath(const std::string& name) {
  const bool json = name.size() > 5 && name.compare(name.size() - 5, 5, ".json") == 0;
  if (json || name.rfind("./", 0) == 0 || name.rfind("/", 0) == 0 || name.rfind("../", 0) == 0) return name;
  return assetsDir() + "/scenes/" + name + ".json";
}

std::string relativePath(const std::string& path, const std::string& folder) {
  std::error_code ec;
  const fs::path base = fs::absolute(folder.empty() ? "." : folder, ec).lexically_normal();
  const fs::path rel = fs::absolute(path, ec).lexically_normal().lexically_relative(base);
  return rel.empty() ? path : rel.string();
}

bool samePath(const std::string& a, const std::string& b) {
  std::error_code ea, eb;
  if (fs::equivalent(a, b, ea)) return true;
  const fs::path pa = fs::weakly_canonical(fs::absolute(a), ea).lexically_normal();
  const fs::path pb = fs::weakly_canonical(fs::absolute(b), eb).lexically_normal();
  return !ea && !eb && pa == pb;
}

void checkWritable(const std::string& path, const std::string& what) {
  fs::path p(path);
  fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::exists(dir, ec)) {
    fs::create_directories(dir, ec);
    if (ec) throw UsageError(what + ": cannot create folder " + dir.string() + ": " + ec.message());
  }
  if (!fs::is_directory(dir, ec)) throw UsageError(what + ": " + dir.string() + " is not a folder");
  if (access(dir.c_str(), W_OK) != 0)
    throw UsageError(what + ": cannot write in " + dir.string() + ": " + std::strerror(errno));
  if (fs::is_directory(p, ec)) throw UsageError(what + ": " + path + " is a folder; give a file name");
  removeStaleTemporaries(path);
  const std::string probe = temporaryName(path);
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    if (errno != EEXIST) throw UsageError(what + ": cannot create a file in " + dir.string() + ": " + std::strerror(errno));
  } else {
    ::close(fd);
    ::unlink(probe.c_str());
  }
}

std::string temporaryName(const std::string& output) { return output + ".part" + std::to_string(getpid()); }

void removeStaleTemporaries(const std::string& output) {
  fs::path p(output);
  while (p.has_filename() == false && p.has_parent_path() && p != p.parent_path()) p = p.parent_path();  // "dir/"
  const std::string prefix = p.filename().string() + ".part";
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string digits = name.substr(prefix.size());
    if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    const pid_t pid = static_cast<pid_t>(std::stol(digits));
    if (pid == getpid() || kill(pid, 0) == 0 || errno != ESRCH) continue;  // alive, or not ours to judge
    std::error_code rm;
    fs::remove_all(it->path(), rm);
  }
}

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  checkWritable(path_, path_);
  temp_ = temporaryName(path_);
  out_.open(temp_, std::ios::binary | std::ios::trunc);
  if (!out_) throw UsageError(path_ + ": cannot create " + temp_ + ": " + std::strerror(errno));
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    out_.close();
    std::remove(temp_.c_str());
  }
}

void AtomicFile::commit() {
  out_.flush();
  if (!out_) throw std::runtime_error(path_ + ": write failed (disk full?)");
  out_.close();
  std::error_code ec;
  fs::rename(temp_, path_, ec);
  if (ec) throw std::runtime_error(path_ + ": cannot rename " + temp_ + " into place: " + ec.message());
  committed_ = true;
}

int runCommandLine(CLI::App& app, int argc, char** argv, const char* program, const std::function<int()>& action) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : kExitBadInput;
  }
  try {
    return action();
  } catch (const Interrupted& e) {
    std::cerr << program << ": " << e.what() << "\n";
    return kExitInterrupted;
  } catch (const UsageError& e) {
    std::cerr << program << ": " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << program << ": " << e.what() << "\n";
    return kExitFailure;
  }
}

double nowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

namespace {
volatile std::sig_atomic_t gSignal = 0;
int gGuards = 0;
extern "C" void onSignal(int sig) { gSignal = sig; }
}  // namespace

InterruptGuard::InterruptGuard() {
  if (gGuards++ == 0) {
    gSignal = 0;
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
  }
}

InterruptGuard::~InterruptGuard() {
  if (--gGuards == 0) {
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
  }
}

bool InterruptGuard::interrupted() { return gSignal != 0; }
int InterruptGuard::signal() { return gSignal; }

namespace {
// How long a job runs before its bar appears [s]: 1, or $SUBSTEP_PROGRESS_DELAY (the tests set 0,
// so that a bar they look for does not depend on how fast the machine is).
double progressDelay() {
  const char* e = std::getenv("SUBSTEP_PROGRESS_DELAY");
  if (!e || !*e) return 1.0;
  char* end = nullptr;
  const double d = std::strtod(e, &end);
  return *end == '\0' && d >= 0 && d < 1e6 ? d : 1.0;
}
}  // namespace

Progress::Progress(std::string label, long long total, bool show)
    : label_(std::move(label)),
      total_(total),
      start_(nowSeconds()),
      delay_(progressDelay()),
      enabled_(show && isatty(STDERR_FILENO)) {}

void Progress::update(long long done) {
  if (!enabled_) return;
  const double t = nowSeconds();
  const double el = t - start_;
  if (el < delay_ || t - lastDraw_ < 0.2) return;
  lastDraw_ = t;
  shown_ = true;
  const double rate = done / std::max(el, 1e-9);
  const double left = rate > 0 ? (total_ - done) / rate : 0;
  const int width = 30;
  const int filled = total_ > 0 ? static_cast<int>(width * done / total_) : 0;
  std::string bar(static_cast<size_t>(filled), '#');
  bar.resize(width, '.');
  std::fprintf(stderr, "\r%s [%s] %lld/%lld  %.1f/s  %.0f s left   ", label_.c_str(), bar.c_str(), done, total_, rate,
               left);
  std::fflush(stderr);
}

void Progress::clear() {
  if (!shown_) return;
  std::fprintf(stderr, "\r%*s\r", 80, "");
  std::fflush(stderr);
  lastDraw_ = -1;
}

void Progress::finish() {
  if (!shown_) return;
  std::fprintf(stderr, "\r%s done: %lld in %.1f s%40s\n", label_.c_str(), total_, nowSeconds() - start_, "");
}

}  // namespace substep::app
