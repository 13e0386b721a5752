// Pieces the subcommands share: solver options on the command line, exit codes, atomic outputs.
#pragma once

#include "physics/scene_file.h"
#include "physics/settings.h"

#include <CLI/CLI.hpp>

#include <fstream>
#include <functional>
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

// The solver options shared by `run`, `render` and `bench`.
struct SolverOptions {
  std::string algo, preset;
  std::optional<double> dt, omega, tolerance, kappa, tau, slop;
  std::optional<int> substeps, iterations;
  bool warmStart = false, noWarmStart = false, blockSolve = false, noBlockSolve = false;
  bool splitImpulse = false, noSplitImpulse = false;

  void add(CLI::App& cmd);
  SolverOverrides overrides() const;
};

// Settings for a scene: the scene's solver block, overridden by the command line, resolved with
// the algorithm's defaults. Throws UsageError.
SolverSettings resolveSettings(const Scene& scene, const SolverOverrides& commandLine);

// One line describing the settings, e.g. "a5 (Havok stepping, actual) h=1/60 n=4 m=1 κ=1 τ=0.6".
std::string describe(const SolverSettings& s);

// Loads a scene, turning its errors into UsageError.
Scene load(const std::string& path);

// Where assets live: $SUBSTEP_ASSETS, else the source tree's assets/.
std::string assetsDir();

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

// Makes sure the folder of `path` exists and a file can be created there; throws UsageError.
void checkWritable(const std::string& path, const std::string& what);

// Progress on stderr for long jobs: frames done, rate, time left. Silent for the first second.
class Progress {
 public:
  Progress(std::string label, long long total);
  void update(long long done);
  void finish();

 private:
  std::string label_;
  long long total_;
  double start_;
  double lastDraw_ = -1;
  bool shown_ = false;
};

double nowSeconds();

// The main of a command-line program: parses argv into `app`, then runs `action`. Exit status:
// 0 after --help, kExitBadInput for bad arguments or a UsageError, kExitFailure for any other
// exception, else what `action` returns; errors go to stderr as "program: message".
int runCommandLine(CLI::App& app, int argc, char** argv, const char* program, const std::function<int()>& action);

}  // namespace substep::app
