// substep run: steps a scene and writes what happened (trajectory CSV, metrics JSON, a summary).
#include "app/commands.h"
#include "app/common.h"
#include "physics/failure.h"
#include "physics/world.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>

namespace substep::app {

namespace {

namespace fs = std::filesystem;

struct RunOptions {
  std::string scene;
  SolverOptions solver;
  std::optional<long long> steps;
  std::optional<double> seconds;
  std::optional<std::string> trajectory, metrics;
  long long every = 1;
  bool quiet = false;
  SceneLimits limits;
};

// A CSV field: quoted when it holds a comma or a quote (body names may).
std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

void writeTrajectoryRows(std::ostream& o, const Model& m, const State& s) {
  for (size_t i = 0; i < m.bodies.size(); ++i) {
    if (m.bodies[i].isStatic) continue;
    const BodyState& b = s.bodies[i];
    const Vec3 w = b.worldAngularVelocity();
    o << s.step << ',' << s.time << ',' << csvField(m.bodies[i].name) << ',' << b.x.x() << ',' << b.x.y() << ',' << b.x.z() << ','
      << b.q.w() << ',' << b.q.x() << ',' << b.q.y() << ',' << b.q.z() << ',' << b.v.x() << ',' << b.v.y() << ','
      << b.v.z() << ',' << w.x() << ',' << w.y() << ',' << w.z() << '\n';
  }
}

// Largest distance of a dynamic body from where it started [m].
double maxDisplacement(const Scene& scene, const State& s) {
  double worst = 0;
  for (size_t i = 0; i < scene.model.bodies.size(); ++i)
    if (!scene.model.bodies[i].isStatic) worst = std::max(worst, (s.bodies[i].x - scene.initial.bodies[i].x).norm());
  return worst;
}

}  // namespace

void addRunCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<RunOptions>();
  CLI::App* cmd = app.add_subcommand("run", "Step a scene and report what happened");
  cmd->add_option("scene", opt->scene, "Scene file (JSON), e.g. assets/scenes/stack.json")->required();
  opt->solver.add(*cmd);
  auto* steps = cmd->add_option("--steps", opt->steps, "Number of steps to take")->check(CLI::Range(1LL, 1000000000LL));
  auto* secs = cmd->add_option("--seconds", opt->seconds, "Simulated time to cover [s] (default 5)")
                   ->check(finiteIn(1e-9, 1e7));
  steps->excludes(secs);
  cmd->add_option("--trajectory", opt->trajectory, "Write every body's state to this CSV file");
  cmd->add_option("--every", opt->every, "Keep every K-th step in the trajectory and metrics (first and last always)")
      ->check(CLI::Range(1LL, 1000000000LL));
  cmd->add_option("--metrics", opt->metrics, "Write stage times, constraint violation and energies to this JSON file");
  cmd->add_flag("--quiet,-q", opt->quiet, "Print nothing but errors (no progress bar either)");
  addMaxBodies(*cmd, opt->limits);
  cmd->callback([opt, &action] {
    action = [opt] {
      for (const auto* o : {&opt->trajectory, &opt->metrics})
        if (*o && (*o)->empty())
          throw UsageError(std::string(o == &opt->trajectory ? "--trajectory" : "--metrics") +
                           ": expected a file name, got an empty one");
      if (opt->trajectory && opt->metrics && samePath(*opt->trajectory, *opt->metrics))
        throw UsageError("--trajectory and --metrics name the same file " + *opt->metrics +
                         "; give each its own");
      const Scene scene = load(opt->scene, opt->limits);
      const SolverSettings settings = resolveSettings(scene, opt->solver.overrides());
      const long long steps =
          opt->steps ? *opt->steps : static_cast<long long>(std::ceil(opt->seconds.value_or(5.0) / settings.dt - 1e-9));

      std::unique_ptr<AtomicFile> traj, metrics;
      if (opt->trajectory) {
        traj = std::make_unique<AtomicFile>(*opt->trajectory);
        traj->out() << std::setprecision(17);
        traj->out() << "step,time,body,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz\n";
      }
      if (opt->metrics) metrics = std::make_unique<AtomicFile>(*opt->metrics);

      World world(scene.model, settings, scene.initial);
      FailureWatch watch(scene.model, scene.initial);
      nlohmann::json series = {{"step", nlohmann::json::array()},   {"time", nlohmann::json::array()},
                               {"kinetic", nlohmann::json::array()}, {"potential", nlohmann::json::array()},
                               {"penetration", nlohmann::json::array()}, {"joint_error", nlohmann::json::array()},
                               {"contacts", nlohmann::json::array()}, {"iterations", nlohmann::json::array()},
                               {"moved", nlohmann::json::array()}};
      double worstPen = 0, worstJoint = 0;
      auto sample = [&](const StepReport* r) {
        const State& s = world.state();
        if (traj) writeTrajectoryRows(traj->out(), scene.model, s);
        const double pen = world.maxPenetration(), je = world.maxJointError();
        worstPen = std::max(worstPen, pen);
        worstJoint = std::max(worstJoint, je);
        series["step"].push_back(s.step);
        series["time"].push_back(s.time);
        series["kinetic"].push_back(world.kineticEnergy());
        series["potential"].push_back(world.potentialEnergy());
        series["penetration"].push_back(pen);
        series["joint_error"].push_back(je);
        series["contacts"].push_back(r ? r->contactPoints : 0);
        series["iterations"].push_back(r ? r->solver.iterations : 0);
        series["moved"].push_back(maxDisplacement(scene, s));
      };
      if (!opt->quiet)
        std::cout << "scene     " << scene.file << " (" << scene.model.dynamicCount() << " dynamic bodies, "
                  << scene.model.joints.size() << " joints)\n"
                  << "solver    " << settingsLine(settings) << "\n";
      sample(nullptr);
      Progress progress("run", steps, !opt->quiet);
      InterruptGuard interrupt;
      const double wall0 = nowSeconds();
      long long done = 0;
      bool finite = true;
      double maxResidual = 0;
      long long maxIterations = 0, sumIterations = 0;
      long long directMethods[4] = {0, 0, 0, 0};  // A1: steps answered by Dantzig, Lemke, Gauss-Seidel
      int maxContacts = 0;
      long long sumPairs = 0, sumCached = 0;  // broadphase pairs, and those whose manifold was kept
      std::string stopReason;
      for (long long k = 1; k <= steps; ++k) {
        if (InterruptGuard::interrupted()) {
          progress.finish();
          std::cerr << "substep run: interrupted at step " << k - 1 << " of " << steps << "; no output written\n";
          return kExitInterrupted;  // the AtomicFiles remove their temporaries
        }
        const StepReport& r = world.step();
        done = world.state().step;
        watch.observe(world.state(), r.finite);
        maxResidual = std::max(maxResidual, r.solver.residual);
        maxIterations = std::max<long long>(maxIterations, r.solver.iterations);
        sumIterations += r.solver.iterations;
        if (r.solver.directMethod >= 1 && r.solver.directMethod <= 3) ++directMethods[r.solver.directMethod];
        maxContacts = std::max(maxContacts, r.contactPoints);
        sumPairs += r.pairs;
        sumCached += r.cachedPairs;
        if (r.overloaded && k == 1)
          throw UsageError(scene.file + ": the initial configuration: " + r.problem +
                           "; move the bodies apart (a scene starts with bodies touching, not inside each other)");
        if (!r.finite) {
          finite = false;
          stopReason = std::string(r.overloaded ? "the simulation stopped" : "the simulation diverged") + " at step " +
                       std::to_string(k) + " (t = " + std::to_string(world.state().time) + " s): " + r.problem;
          break;
        }
        if (k % opt->every == 0 || k == steps) sample(&r);
        progress.update(k);
      }
      progress.finish();
      const double wall = nowSeconds() - wall0;

      // How far each body got from where it started.
      double maxMove = 0;
      std::string mover;
      for (size_t i = 0; i < scene.model.bodies.size(); ++i) {
        if (scene.model.bodies[i].isStatic) continue;
        const double d = (world.state().bodies[i].x - scene.initial.bodies[i].x).norm();
        if (d > maxMove) maxMove = d, mover = scene.model.bodies[i].name;
      }
      const StageTimes& T = world.totalTimes();
      const double per = 1e3 / std::max<long long>(done, 1);
      if (metrics) {
        nlohmann::json j;
        j["scene"] = scene.file;
        j["algorithm"] = algorithmName(settings.algorithm);
        j["settings"] = {{"dt", settings.dt},         {"substeps", settings.substeps}, {"iterations", settings.iterations},
                         {"omega", settings.omega},   {"tolerance", settings.tolerance}, {"kappa", settings.kappa},
                         {"tau", settings.tau},       {"slop", settings.slop},       {"warm_start", settings.warmStart},
                         {"block_solve", settings.blockSolve}};
        j["steps"] = done;
        j["time"] = world.state().time;
        j["finite"] = finite;
        if (!finite) j["stopped"] = stopReason;
        j["wall_seconds"] = wall;
        j["stage_ms_per_step"] = {{"s1_geometry", T.s1 * per}, {"s2_formulation", T.s2 * per},
                                  {"s3_velocities", T.s3 * per}, {"s4_coordinates", T.s4 * per},
                                  {"total", T.total() * per}};
        j["violation"] = {{"max_penetration", worstPen}, {"max_joint_error", worstJoint}};
        j["pairs_per_step"] = static_cast<double>(sumPairs) / std::max<long long>(done, 1);
        j["pairs_kept"] = sumPairs ? static_cast<double>(sumCached) / sumPairs : 0.0;
        j["solver"] = {{"max_iterations", maxIterations},
                       {"mean_iterations", static_cast<double>(sumIterations) / std::max<long long>(done, 1)},
                       {"max_residual", maxResidual}, {"max_contact_points", maxContacts}};
        if (settings.algorithm == Algorithm::A1)  // which of A1's solvers answered, in steps
          j["solver"]["direct_method_steps"] = {
              {"dantzig", directMethods[1]}, {"lemke", directMethods[2]}, {"gauss_seidel", directMethods[3]}};
        j["max_displacement"] = {{"body", mover}, {"metres", maxMove}};
        const FailureReport& f = watch.report();
        auto time = [](double t) { return t < 0 ? nlohmann::json(nullptr) : nlohmann::json(t); };
        j["failure"] = {{"verdict", f.verdict()},          {"sag_time", time(f.sagTime)},
                        {"collapse_time", time(f.collapseTime)}, {"diverge_time", time(f.divergeTime)},
                        {"max_sag", f.maxSag},              {"max_sideways", f.maxSideways},
                        {"max_speed", f.maxSpeed},          {"max_energy_gain", f.maxEnergyGain},
                        {"collapsed_body", f.collapsedBody}};
        j["series"] = series;
        metrics->out() << j.dump(1) << '\n';
        metrics->commit();
      }
      if (traj) traj->commit();

      if (!opt->quiet) {
        std::cout << std::fixed << std::setprecision(3);
        std::cout << "stepped   " << done << " steps, " << world.state().time << " s simulated in " << wall << " s wall\n"
                  << "per step  " << T.total() * per << " ms: s1 geometry " << T.s1 * per << ", s2 formulation "
                  << T.s2 * per << ", s3 velocities " << T.s3 * per << ", s4 coordinates " << T.s4 * per << "\n"
                  << "contacts  up to " << maxContacts << " points; iterations up to " << maxIterations << "; pairs "
                  << sumPairs / std::max<long long>(done, 1) << " a step, "
                  << (sumPairs ? 100.0 * sumCached / sumPairs : 0.0) << " % kept without the narrowphase\n"
                  << std::setprecision(4) << "violation max penetration " << worstPen * 1e3 << " mm, max joint error "
                  << worstJoint * 1e3 << " mm\n"
                  << "energy    kinetic " << world.kineticEnergy() << " J, potential " << world.potentialEnergy() << " J\n"
                  << "moved     largest displacement " << maxMove * 1e2 << " cm (" << mover << ")\n"
                  << "verdict   " << watch.report().verdict()
                  << (watch.report().collapsedBody.empty() ? "" : " (" + watch.report().collapsedBody + ")")
                  << "; fastest body " << watch.report().maxSpeed << " m/s\n";
        if (settings.algorithm == Algorithm::A1)
          std::cout << "a1 solves " << directMethods[1] << " steps by Dantzig, " << directMethods[2] << " by Lemke, "
                    << directMethods[3] << " by Gauss-Seidel and polish\n";
        if (traj) std::cout << "wrote     " << *opt->trajectory << "\n";
        if (metrics) std::cout << "wrote     " << *opt->metrics << "\n";
      }
      if (!finite) {
        std::cerr << "substep run: stopped: " << stopReason << "; outputs hold the steps before it\n";
        return kExitNonFinite;
      }
      return 0;
    };
  });
}

}  // namespace substep::app
