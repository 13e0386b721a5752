#include "app/common.h"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <sstream>

#ifndef SUBSTEP_SOURCE_DIR
#define SUBSTEP_SOURCE_DIR "."
#endif

namespace substep::app {

namespace fs = std::filesystem;

void SolverOptions::add(CLI::App& cmd) {
  cmd.add_option("--algo", algo, "Algorithm of the report: a1 (direct), a2 (PGS/PSOR), a3, a4, a5 (Havok sub-stepping)")
      ->check(CLI::IsMember({"a1", "a2", "a3", "a4", "a5"}));
  cmd.add_option("--preset", preset, "Havok preset for a3-a5: 2|4|8 sub-steps, soft|medium|hard, e.g. 4-medium");
  cmd.add_option("--dt", dt, "Time step h [s] (default from the scene, else 1/60)")->check(CLI::Range(1e-6, 1.0));
  cmd.add_option("--substeps", substeps, "Sub-steps n per step (a3-a5; default 4)")->check(CLI::Range(1, 1000));
  cmd.add_option("--iterations", iterations, "a2: iteration cap (default 10); a3-a5: micro-iterations m (default 1)")
      ->check(CLI::Range(1, 100000));
  cmd.add_option("--omega", omega, "a2: over-relaxation ω, 0 < ω < 2 (default 1)")->check(CLI::Range(1e-6, 1.999999));
  cmd.add_option("--tolerance", tolerance, "a2: stop iterating when no row's velocity changes more [m/s] (default 1e-6)")
      ->check(CLI::Range(0.0, 1e6));
  cmd.add_option("--kappa", kappa, "κ for a3-a5 (default 1.0)")->check(CLI::Range(1e-6, 10.0));
  cmd.add_option("--tau", tau, "τ for a3-a5 (default 0.6)")->check(CLI::Range(0.0, 10.0));
  cmd.add_option("--slop", slop, "Allowed penetration, the report's hi [m] (default 0.001)")->check(CLI::Range(0.0, 1.0));
  cmd.add_flag("--warm-start", warmStart, "Start each step from the previous step's impulses");
  cmd.add_flag("--no-warm-start", noWarmStart, "Do not warm start");
  cmd.add_flag("--block-solve", blockSolve, "Solve unbounded ('stable') constraints as blocks");
  cmd.add_flag("--no-block-solve", noBlockSolve, "Solve every row on its own");
  cmd.add_flag("--split-impulse", splitImpulse,
               "Correct contact penetration with pseudo-velocities, apart from the velocity solve");
  cmd.add_flag("--no-split-impulse", noSplitImpulse, "Correct penetration through the bias, as the report does");
}

SolverOverrides SolverOptions::overrides() const {
  SolverOverrides o;
  if (!algo.empty()) o.algorithm = parseAlgorithm(algo);
  if (!preset.empty()) o.preset = preset;
  o.dt = dt;
  o.substeps = substeps;
  o.iterations = iterations;
  o.omega = omega;
  o.tolerance = tolerance;
  o.kappa = kappa;
  o.tau = tau;
  o.slop = slop;
  if (warmStart && noWarmStart) throw UsageError("--warm-start and --no-warm-start contradict each other");
  if (blockSolve && noBlockSolve) throw UsageError("--block-solve and --no-block-solve contradict each other");
  if (splitImpulse && noSplitImpulse)
    throw UsageError("--split-impulse and --no-split-impulse contradict each other");
  if (warmStart) o.warmStart = true;
  if (noWarmStart) o.warmStart = false;
  if (blockSolve) o.blockSolve = true;
  if (noBlockSolve) o.blockSolve = false;
  if (splitImpulse) o.splitImpulse = true;
  if (noSplitImpulse) o.splitImpulse = false;
  return o;
}

SolverSettings resolveSettings(const Scene& scene, const SolverOverrides& cl) {
  const SolverOverrides merged = scene.solver.withCommandLine(cl);
  const Algorithm algo = merged.algorithm.value_or(Algorithm::A2);
  if (!subSteps(algo)) {
    if (cl.substeps && *cl.substeps != 1)
      throw UsageError(std::string("--substeps: ") + algorithmName(algo) +
                       " does not sub-step (the report's A1/A2 take one step of h); use --dt for a smaller step, "
                       "or --algo a3|a4|a5");
    if (cl.preset)
      throw UsageError(std::string("--preset: presets are Havok's sub-stepping settings; use --algo a3|a4|a5 with it"));
    if (cl.kappa || cl.tau)
      throw UsageError(std::string("--kappa/--tau: ") + algorithmName(algo) + " has no κ or τ; use --algo a3|a4|a5");
  }
  SolverOverrides use = merged;
  if (!cl.preset && cl.algorithm && merged.preset && !subSteps(algo)) use.preset.reset();  // scene preset, a1/a2 asked
  try {
    return resolve(use);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("solver settings (") + scene.file + " or the command line): " + e.what());
  }
}

std::string describe(const SolverSettings& s) {
  std::ostringstream o;
  o << algorithmName(s.algorithm) << " (" << algorithmTitle(s.algorithm) << ") h=";
  const double inv = 1.0 / s.dt;
  if (std::abs(inv - std::round(inv)) < 1e-9)
    o << "1/" << std::llround(inv);
  else
    o << s.dt;
  switch (s.algorithm) {
    case Algorithm::A1: break;
    case Algorithm::A2: o << " iterations<=" << s.iterations << " ω=" << s.omega << " tol=" << s.tolerance; break;
    default: o << " n=" << s.substeps << " m=" << s.iterations << " κ=" << s.kappa << " τ=" << s.tau; break;
  }
  if (s.warmStart) o << " warm-start";
  if (s.splitImpulse) o << " split-impulse";
  if (s.blockSolve) o << " blocks";
  return o.str();
}

Scene load(const std::string& path) {
  try {
    return loadScene(path);
  } catch (const SceneError& e) {
    throw UsageError(e.what());
  }
}

std::string assetsDir() {
  if (const char* env = std::getenv("SUBSTEP_ASSETS")) return env;
  return std::string(SUBSTEP_SOURCE_DIR) + "/assets";
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
}

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  checkWritable(path_, path_);
  temp_ = path_ + ".part" + std::to_string(getpid());
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

Progress::Progress(std::string label, long long total) : label_(std::move(label)), total_(total), start_(nowSeconds()) {}

void Progress::update(long long done) {
  const double t = nowSeconds();
  const double el = t - start_;
  if (el < 1.0 || t - lastDraw_ < 0.2) return;
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

void Progress::finish() {
  if (!shown_) return;
  std::fprintf(stderr, "\r%s done: %lld in %.1f s%40s\n", label_.c_str(), total_, nowSeconds() - start_, "");
}

}  // namespace substep::app
