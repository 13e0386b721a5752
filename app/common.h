// Pieces the subcommands share: solver options on the command line, exit codes, atomic outputs.
#pragma once

#include "physics/scene_file.h"
#include "physics/settings.h"

#include <CLI/CLI.hpp>

#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>

namespace substep::app {

// Exit status: 0 done, 1 failure at run time, 2 bad input (scene file, arguments), 3 the
// simulation stopped because a value went non-finite.
constexpr int kExitFailure = 1;
constexpr int kExitBadInput = 2;
constexpr int kExitNonFinite = 3;

// An error in what the user gave us: reported as is, exit status 2.
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The solver options shared by `run`, `render` and `bench`: one per row of the settings table
// (physics/settings.h), each parsed and range-checked by it; flags have a --no- form.
struct SolverOptions {
  std::map<std::string, std::optional<std::string>> values;  // by setting key, as typed
  std::map<std::string, std::pair<bool, bool>> flags;         // by setting key: --x, --no-x

  void add(CLI::App& cmd);
  // Throws UsageError naming the option ("--kappa: expected a number in (0, 10], got \"nan\"").
  SolverOverrides overrides() const;
};

// A number option's check: finite and within [lo, hi] ("nan", "inf" and "1e999" are refused,
// which CLI::Range lets through).
CLI::Validator finiteIn(double lo, double hi);

// Settings for a scene: the scene's solver block, overridden by the command line, resolved with
// the algorithm's defaults. Throws UsageError.
SolverSettings resolveSettings(const Scene& scene, const SolverOverrides& commandLine);

// `given` with threads set to the machine's cores for a scene of kEveryCoreFromBodies moving
// bodies or more, unless the scene or `given` sets it: what serve and render step with (the
// trajectory is the same on any number of threads).
constexpr long kEveryCoreFromBodies = 3000;
SolverOverrides onEveryCore(const Scene& scene, SolverOverrides given);

// Loads a scene, turning its errors into UsageError.
Scene load(const std::string& path, const SceneLimits& lim = {});
// --max-bodies N, the cap on a scene's bodies and joints.
void addMaxBodies(CLI::App& cmd, SceneLimits& lim);

// Where assets live: $SUBSTEP_ASSETS, else the source tree's assets/.
std::string assetsDir();
// A scene named on the command line: a path (it holds a '/' or ends in .json) as it is, else a
// name in the assets' scenes/ folder: "chain" -> <assets>/scenes/chain.json, "atlas/card_house"
// -> <assets>/scenes/atlas/card_house.json.
std::string scenePath(const std::string& name);

// Temporary outputs are named <output>.part<pid>. Removes those next to `output` whose process
// is gone (a run killed with SIGKILL, or a crash), so they do not pile up.
void removeStaleTemporaries(const std::string& output);
std::string temporaryName(const std::string& output);  // <output>.part<pid of this process>

// A file written under a temporary name and renamed over the target when committed; removed
// if never committed. Fails early with a clear UsageError if the folder is not writable.
class AtomicFile {
 public:
  explicit AtomicFile(std::string path);
  ~AtomicFile();
  std::ofstream& out() { return out_; }
  const std::string& tempPath() const { return temp_; }
  void commit();

 private:
  std::string path_, temp_;
  std::ofstream out_;
  bool committed_ = false;
};

// Whether two paths name the same file (existing or not): "x.csv" and "./x.csv" do.
bool samePath(const std::string& a, const std::string& b);
// `path` relative to `folder` ("" for the current one), as a file in that folder links it:
// ("out/recs/a.rec", "out") -> "recs/a.rec". Neither needs to exist.
std::string relativePath(const std::string& path, const std::string& folder);

// Makes sure the folder of `path` exists and a file can be created there (it creates and removes
// `path`'s temporary name, so a folder that only looks writable, like /proc, is caught before any
// work), and removes stale temporaries of `path`; throws UsageError.
void checkWritable(const std::string& path, const std::string& what);

// SIGINT and SIGTERM set a flag while one of these lives, so that long jobs stop between steps
// or frames and remove their temporary outputs (their destructors) before exiting with 130.
class InterruptGuard {
 public:
  InterruptGuard();
  ~InterruptGuard();
  static bool interrupted();
  static int signal();  // the signal received, 0 if none
};
constexpr int kExitInterrupted = 130;
// Thrown where a long job notices the interrupt: runCommandLine prints "PROGRAM: interrupted; no
// output written" and exits with 130, after the outputs' destructors removed their temporaries.
struct Interrupted : std::runtime_error {
  Interrupted() : std::runtime_error("interrupted; no output written") {}
};

// Progress on stderr for long jobs: frames done, rate, time left. Silent for the first second
// ($SUBSTEP_PROGRESS_DELAY seconds if set), when `show` is false (-q) and when stderr is not a
// terminal (a log file gets no bar).
class Progress {
 public:
  Progress(std::string label, long long total, bool show = true);
  void update(long long done);
  // Takes the bar off the line, so that a message can be printed there; the next update redraws it.
  void clear();
  void finish();

 private:
  std::string label_;
  long long total_;
  double start_;
  double delay_;
  double lastDraw_ = -1;
  bool shown_ = false;
  bool enabled_ = true;
};

double nowSeconds();

// The main of a command-line program: parses argv into `app`, then runs `action`. Exit status:
// 0 after --help, kExitBadInput for bad arguments or a UsageError, kExitFailure for any other
// exception, else what `action` returns; errors go to stderr as "program: message".
int runCommandLine(CLI::App& app, int argc, char** argv, const char* program, const std::function<int()>& action);

}  // namespace substep::app
