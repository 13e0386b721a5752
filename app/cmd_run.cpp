// substep run: steps a scene and writes what happened (trajectory CSV, metrics JSON, a recording,
// a summary), under substep's settings or a method spec (--method), a peer engine's too.
// The stepping is the run driver's (physics/run.h); this file says what to watch and presents it.
#include "app/commands.h"
#include "app/common.h"
#include "app/run_observers.h"
#include "lab/method.h"
#include "lab/peers.h"
#include "lab/record.h"
#include "lab/runner.h"
#include "physics/failure.h"
#include "physics/recording.h"
#include "physics/settings_json.h"
#include "physics/state_hash.h"
#include "physics/world.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <iomanip>
#include <iostream>

namespace substep::app {

namespace {

using json = nlohmann::json;

struct RunOptions {
  std::string scene;
  SolverOptions solver;
  std::optional<long long> steps;
  std::optional<double> seconds;
  std::optional<std::string> trajectory, metrics, record, method;
  long long every = 1;
  bool quiet = false;
  SceneLimits limits;
};

// What `run` reports of a World's run: a series at the kept steps, the worst violations, the
// solver's statistics over every step, and the failure watch's verdict.
class RunSummary final : public RunObserver {
 public:
  RunSummary(const Scene& scene, long long every, long long planned)
      : scene_(scene), watch_(scene.model, scene.initial), every_(every), planned_(planned) {
    for (const char* k : {"step", "time", "kinetic", "potential", "penetration", "joint_error", "contacts", "iterations", "moved"})
      series[k] = json::array();
  }
  void begin(const Engine& e) override { sample(*e.world(), nullptr); }
  void observe(const Engine& e, const StepRecord& r) override {
    watch_.observe(e.state(), r.finite);
    if (!r.finite) return;
    const StepReport& rep = *r.report;
    maxResidual = std::max(maxResidual, rep.solver.residual);
    maxIterations = std::max<long long>(maxIterations, rep.solver.iterations);
    sumIterations += rep.solver.iterations;
    if (rep.solver.directMethod >= 1 && rep.solver.directMethod <= 3) ++directMethods[rep.solver.directMethod];
    maxContacts = std::max(maxContacts, rep.contactPoints);
    sumPairs += rep.pairs;
    sumCached += rep.cachedPairs;
    // Sleeping: the step's cost while every dynamic body sleeps against while any is awake.
    asleepEnd = rep.asleep;
    const bool settled = rep.asleep > 0 && rep.asleep == scene_.model.dynamicCount();
    (settled ? settledSeconds : awakeSeconds) += r.seconds;
    (settled ? settledSteps : awakeSteps) += 1;
    if (settled && settledAt < 0) settledAt = e.state().time;
    if (!settled) settledAt = -1;
    if (r.step % every_ == 0 || r.step == planned_) sample(*e.world(), &rep);
  }
  const FailureReport& failure() const { return watch_.report(); }

  json series;
  double worstPen = 0, worstJoint = 0, maxResidual = 0;
  long long maxIterations = 0, sumIterations = 0, sumPairs = 0, sumCached = 0;
  long long directMethods[4] = {0, 0, 0, 0};  // A1: steps answered by Dantzig, Lemke, Gauss-Seidel
  int maxContacts = 0;
  int asleepEnd = 0;                  // dynamic bodies asleep after the last step
  double settledAt = -1;              // since when every dynamic body sleeps [s]; -1: not now
  double settledSeconds = 0, awakeSeconds = 0;
  long long settledSteps = 0, awakeSteps = 0;

 private:
  void sample(const World& w, const StepReport* r) {
    const State& s = w.state();
    const double pen = w.maxPenetration(), je = w.maxJointError();
    worstPen = std::max(worstPen, pen);
    worstJoint = std::max(worstJoint, je);
    series["step"].push_back(s.step);
    series["time"].push_back(s.time);
    series["kinetic"].push_back(w.kineticEnergy());
    series["potential"].push_back(w.potentialEnergy());
    series["penetration"].push_back(pen);
    series["joint_error"].push_back(je);
    series["contacts"].push_back(r ? r->contactPoints : 0);
    series["iterations"].push_back(r ? r->solver.iterations : 0);
    series["moved"].push_back(largestDisplacement(scene_.model, scene_.initial, s).metres);
  }

  const Scene& scene_;
  FailureWatch watch_;
  long long every_, planned_;
};

json metricsJson(const Scene& scene, const World& world, const RunSummary& sum, const RunOutcome& o,
                 const RunHashes& hashes, long long planned) {
  const SolverSettings& settings = world.settings();
  const StageTimes& T = world.totalTimes();
  const double per = 1e3 / std::max<long long>(o.steps, 1);
  const Displacement d = largestDisplacement(scene.model, scene.initial, world.state());
  json j;
  j["scene"] = scene.file;
  j["algorithm"] = algorithmName(settings.algorithm);
  j["line"] = settingsLine(settings);
  lab::addReproduction(j, scene, "substep", settingsJson(settings), planned, o.steps, hashes);
  j["time"] = world.state().time;
  j["finite"] = !o.stepFailed;
  if (o.end == RunOutcome::End::Diverged) j["stopped"] = o.message;
  j["wall_seconds"] = o.seconds;
  j["stage_ms_per_step"] = {{"s1_geometry", T.s1 * per}, {"s2_formulation", T.s2 * per}, {"s3_velocities", T.s3 * per},
                            {"s4_coordinates", T.s4 * per}, {"total", T.total() * per}};
  j["violation"] = {{"max_penetration", sum.worstPen}, {"max_joint_error", sum.worstJoint}};
  j["pairs_per_step"] = static_cast<double>(sum.sumPairs) / std::max<long long>(o.steps, 1);
  j["pairs_kept"] = sum.sumPairs ? static_cast<double>(sum.sumCached) / sum.sumPairs : 0.0;
  j["solver"] = {{"max_iterations", sum.maxIterations},
                 {"mean_iterations", static_cast<double>(sum.sumIterations) / std::max<long long>(o.steps, 1)},
                 {"max_residual", sum.maxResidual},
                 {"max_contact_points", sum.maxContacts}};
  if (settings.algorithm == Algorithm::A1)  // which of A1's solvers answered, in steps
    j["solver"]["direct_method_steps"] = {
        {"dantzig", sum.directMethods[1]}, {"lemke", sum.directMethods[2]}, {"gauss_seidel", sum.directMethods[3]}};
  j["max_displacement"] = {{"body", d.body >= 0 ? scene.model.bodies[static_cast<size_t>(d.body)].name : ""},
                           {"metres", d.metres}};
  const FailureReport& f = sum.failure();
  auto time = [](double t) { return t < 0 ? json(nullptr) : json(t); };
  j["failure"] = {{"verdict", f.verdict()},          {"sag_time", time(f.sagTime)},
                  {"collapse_time", time(f.collapseTime)}, {"diverge_time", time(f.divergeTime)},
                  {"max_sag", f.maxSag},              {"max_sideways", f.maxSideways},
                  {"max_speed", f.maxSpeed},          {"max_energy_gain", f.maxEnergyGain},
                  {"collapsed_body", f.collapsedBody}};
  if (settings.sleep)
    j["sleep"] = {{"asleep", sum.asleepEnd},
                  {"settled_at", sum.settledAt >= 0 ? json(sum.settledAt) : json(nullptr)},
                  {"settled_ms_per_step", sum.settledSteps ? json(1e3 * sum.settledSeconds / static_cast<double>(sum.settledSteps)) : json(nullptr)},
                  {"awake_ms_per_step", sum.awakeSteps ? json(1e3 * sum.awakeSeconds / static_cast<double>(sum.awakeSteps)) : json(nullptr)}};
  j["series"] = sum.series;
  return j;
}

void printSummary(const Scene& scene, const World& world, const RunSummary& sum, const RunOutcome& o) {
  const StageTimes& T = world.totalTimes();
  const double per = 1e3 / std::max<long long>(o.steps, 1);
  const Displacement d = largestDisplacement(scene.model, scene.initial, world.state());
  const FailureReport& f = sum.failure();
  std::cout << std::fixed << std::setprecision(3);
  std::cout << "stepped   " << o.steps << " steps, " << world.state().time << " s simulated in " << o.seconds << " s\n"
            << "per step  " << T.total() * per << " ms: s1 geometry " << T.s1 * per << ", s2 formulation " << T.s2 * per
            << ", s3 velocities " << T.s3 * per << ", s4 coordinates " << T.s4 * per << "\n"
            << "contacts  up to " << sum.maxContacts << " points; iterations up to " << sum.maxIterations << "; pairs "
            << sum.sumPairs / std::max<long long>(o.steps, 1) << " a step, "
            << (sum.sumPairs ? 100.0 * sum.sumCached / sum.sumPairs : 0.0) << " % kept without the narrowphase\n"
            << std::setprecision(4) << "violation max penetration " << sum.worstPen * 1e3 << " mm, max joint error "
            << sum.worstJoint * 1e3 << " mm\n"
            << "energy    kinetic " << world.kineticEnergy() << " J, potential " << world.potentialEnergy() << " J\n"
            << "moved     largest displacement " << d.metres * 1e2 << " cm ("
            << (d.body >= 0 ? scene.model.bodies[static_cast<size_t>(d.body)].name : "") << ")\n"
            << "verdict   " << f.verdict() << (f.collapsedBody.empty() ? "" : " (" + f.collapsedBody + ")")
            << "; fastest body " << f.maxSpeed << " m/s\n";
  if (world.settings().sleep) {
    std::cout << std::setprecision(3) << "asleep    " << sum.asleepEnd << " of " << scene.model.dynamicCount() << " dynamic bodies at the end";
    if (sum.settledAt >= 0 && sum.settledSteps && sum.awakeSteps) {
      const double settled = 1e3 * sum.settledSeconds / static_cast<double>(sum.settledSteps);
      const double awake = 1e3 * sum.awakeSeconds / static_cast<double>(sum.awakeSteps);
      std::cout << ", all since " << sum.settledAt << " s; a settled step " << settled << " ms against " << awake
                << " ms awake (" << std::defaultfloat << std::setprecision(2) << settled / awake << "x)";
    }
    std::cout << "\n";
  }
  if (world.settings().algorithm == Algorithm::A1)
    std::cout << "a1 solves " << sum.directMethods[1] << " steps by Dantzig, " << sum.directMethods[2] << " by Lemke, "
              << sum.directMethods[3] << " by Gauss-Seidel and polish\n";
}


// --- a peer's run -------------------------------------------------------------------------------

// The one method --method names (a list of values would name several).
lab::Method oneMethod(const std::string& spec) {
  std::vector<lab::Method> m;
  try {
    m = lab::parseMethods(spec);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--method: ") + e.what());
  }
  if (m.size() != 1)
    throw UsageError("--method " + spec + ": names " + std::to_string(m.size()) +
                     " methods; run takes one (`substep sweep --methods` runs a list)");
  return m[0];
}

// A peer (lab/peers.h) steps the scene under the lab's runner, measured as a sweep measures it; the
// metrics file is the sweep's record of the run, which `substep rerun` steps again. A scene the
// peer cannot model is refused with the reason (exit 2), never approximated.
int runPeer(const RunOptions& o, const Scene& scene, const lab::Method& m) {
  const std::string engine = lab::peerDisplayName(m.peer);
  const SolverOverrides commandLine = o.solver.overrides();
  for (const SettingSpec& s : settingTable())
    if (commandLine.has(s) && std::string(s.key) != "dt")
      throw UsageError(std::string("--") + s.flag + " is a setting of substep's algorithms; the " + engine +
                       " peer takes its own in --method (keys: " + findPeer(m.peer)->keys() + ")");
  const std::optional<double> dt = commandLine.get(&SolverSettings::dt);
  if (dt && m.overrides.get(&SolverSettings::dt)) throw UsageError("--dt and --method's h both give the time step; give one");
  if (o.trajectory)
    throw UsageError("--trajectory: not written for a peer; --record keeps every body's state at the kept steps");
  SolverSettings settings;
  try {
    settings = lab::methodSettings(m, scene, dt);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--method: ") + e.what());
  }
  if (const std::string why = lab::peerUnsupported(m.peer, scene.model, scene.initial); !why.empty())
    throw UsageError(scene.file + ": no " + engine + " peer for this scene: " + why);
  const long long planned =
      o.steps ? *o.steps : static_cast<long long>(std::ceil(o.seconds.value_or(5.0) / settings.dt - 1e-9));
  const double seconds = static_cast<double>(planned) * settings.dt;
  std::unique_ptr<AtomicFile> metrics;
  if (o.metrics) metrics = std::make_unique<AtomicFile>(*o.metrics);
  if (o.record) checkWritable(*o.record, "--record " + *o.record);
  std::optional<lab::PreparedReference> reference;
  if (scene.criteria && scene.criteria->reference) {
    try {
      reference = lab::prepareReference(scene, *scene.criteria->reference, seconds);
    } catch (const std::exception& e) {
      throw UsageError(scene.file + ": criteria.reference: " + e.what());
    }
  }
  const lab::PeerSettings peer = lab::peerSettings(m, settings);
  if (!o.quiet)
    std::cout << "scene     " << scene.file << " (" << scene.model.dynamicCount() << " dynamic bodies, "
              << scene.model.joints.size() << " joints)\n"
              << "peer      " << engine << " " << lab::peerVersion(m.peer) << ": " << lab::peerLine(peer) << "\n";

  InterruptGuard interrupt;
  Progress bar("run", planned, !o.quiet);
  lab::RunSetup setup;
  setup.seconds = seconds;
  setup.reference = reference ? &*reference : nullptr;
  setup.recording = o.record.value_or("");
  setup.recordEvery = o.every;
  setup.stop = [&](const lab::Metrics&, double t) {
    bar.update(std::llround(t / settings.dt));
    return InterruptGuard::interrupted() ? std::string(ProgressBar::kInterrupted) : std::string();
  };
  const lab::RunResult r = lab::runMethod(scene, m, setup);
  bar.finish();
  if (!r.stoppedEarly.empty()) {
    std::cerr << "substep run: interrupted at step " << r.stepsDone << " of " << planned << "; no output written\n";
    return kExitInterrupted;
  }
  if (r.refused) throw UsageError(scene.file + ": " + r.stopped);  // a peer that gave up mid-run (MuJoCo's buffers)
  if (metrics) {
    metrics->out() << lab::recordJson(scene, r, seconds, 1).dump(1) << '\n';
    metrics->commit();
  }
  if (!o.quiet) {
    const lab::Metrics& x = r.metrics;
    std::cout << std::fixed << std::setprecision(4) << "stepped   " << r.stepsDone << " steps, " << r.time << " s simulated; "
              << r.cost.msPerStep << " ms a step\n"
              << "violation max penetration " << x.penetrationMax * 1e3 << " mm, max joint error "
              << (x.joints ? x.jointErrorMax * 1e3 : 0.0) << " mm\n"
              << "energy    " << x.energyStart << " J at the start, " << x.energyEnd << " J at the end\n"
              << "moved     largest displacement " << x.displacementMax * 1e2 << " cm (" << x.displacementBody << ")\n"
              << "verdict   " << x.failure.verdict() << "; fastest body " << x.speedMax << " m/s\n";
    if (!x.referenceText.empty()) std::cout << "reference " << x.referenceText << "\n";
    if (x.trajectoryError) std::cout << "error     trajectory " << *x.trajectoryError * 1e3 << " mm (largest)\n";
    if (metrics) std::cout << "wrote     " << *o.metrics << " (substep rerun " << *o.metrics << " runs it again)\n";
    if (!r.recording.empty()) std::cout << "wrote     " << r.recording << "\n";
  }
  if (r.diverged) {
    std::cerr << "substep run: stopped: " << r.stopped << "; outputs hold the steps before it\n";
    return kExitNonFinite;
  }
  return 0;
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
  cmd->add_option("--every", opt->every,
                  "Keep every K-th step in the trajectory, metrics and recording (the first and last always)")
      ->check(CLI::Range(1LL, 1000000000LL));
  cmd->add_option("--metrics", opt->metrics,
                  "Write stage times, constraint violation, energies and what re-runs it (substep rerun) to this JSON "
                  "file");
  cmd->add_option("--record", opt->record,
                  "Write a recording (every body, contact and joint at the kept steps; docs/recordings.md) to this file, "
                  "e.g. out/x.rec");
  cmd->add_option("--method", opt->method,
                  "A method spec (docs/lab.md): one of substep's algorithms with its settings (a5:n=4:m=1; the "
                  "options above still win), or a peer engine: bullet:it=10, ode:it=20:step=quick, mujoco:solver=newton; "
                  "a scene the peer cannot model is refused with the reason (exit 2)");
  cmd->add_flag("--quiet,-q", opt->quiet, "Print nothing but errors (no progress bar either)");
  addMaxBodies(*cmd, opt->limits);
  cmd->callback([opt, &action] {
    action = [opt] {
      const std::pair<const std::optional<std::string>*, const char*> outputs[] = {
          {&opt->trajectory, "--trajectory"}, {&opt->metrics, "--metrics"}, {&opt->record, "--record"}};
      for (const auto& [o, name] : outputs)
        if (*o && (*o)->empty()) throw UsageError(std::string(name) + ": expected a file name, got an empty one");
      for (size_t i = 0; i < 3; ++i)
        for (size_t k = i + 1; k < 3; ++k)
          if (*outputs[i].first && *outputs[k].first && samePath(**outputs[i].first, **outputs[k].first))
            throw UsageError(std::string(outputs[i].second) + " and " + outputs[k].second + " name the same file " +
                             **outputs[k].first + "; give each its own");
      const Scene scene = load(opt->scene, opt->limits);
      SolverOverrides commandLine = opt->solver.overrides();
      if (opt->method) {
        const lab::Method m = oneMethod(*opt->method);
        if (m.isPeer()) return runPeer(*opt, scene, m);
        commandLine = m.overrides.merged(commandLine);
      }
      const SolverSettings settings = resolveSettings(scene, commandLine);
      const long long planned =
          opt->steps ? *opt->steps : static_cast<long long>(std::ceil(opt->seconds.value_or(5.0) / settings.dt - 1e-9));
      std::unique_ptr<AtomicFile> traj, metrics;
      if (opt->trajectory) traj = std::make_unique<AtomicFile>(*opt->trajectory);
      if (opt->metrics) metrics = std::make_unique<AtomicFile>(*opt->metrics);
      std::optional<RecordingWriter> recording;
      if (opt->record) {
        checkWritable(*opt->record, "--record " + *opt->record);
        try {
          recording.emplace(*opt->record, lab::recordingMeta(scene, {{"", settingsJson(settings), "", "substep"}}, opt->every, planned));
        } catch (const RecordingError& e) {
          throw UsageError(std::string("--record: ") + e.what());
        }
      }

      std::unique_ptr<World> world;
      try {
        world = std::make_unique<World>(scene.model, settings, scene.initial);
      } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
      }
      if (!opt->quiet)
        std::cout << "scene     " << scene.file << " (" << scene.model.dynamicCount() << " dynamic bodies, "
                  << scene.model.joints.size() << " joints)\n"
                  << "solver    " << settingsLine(settings) << "\n";
      WorldEngine engine(*world);
      RunDriver run(engine, planned);
      RunSummary summary(scene, opt->every, planned);
      StateHashes hashes(scene.model, planned);
      ProgressBar bar("run", planned, !opt->quiet);
      std::optional<TrajectoryCsv> csv;
      if (traj) csv.emplace(traj->out(), scene.model, opt->every, planned);
      run.add(summary).add(hashes).add(bar);
      if (csv) run.add(*csv);
      std::optional<RecordingObserver> recorder;
      if (recording) run.add(recorder.emplace(*recording, scene.model, 0, opt->every, planned));
      const RunOutcome& o = run.run();

      if (o.end == RunOutcome::End::Stopped) {  // the bar's: Ctrl-C; the AtomicFiles remove their temporaries
        std::cerr << "substep run: interrupted at step " << o.steps << " of " << planned << "; no output written\n";
        return kExitInterrupted;
      }
      if (o.end == RunOutcome::End::Refused) throw UsageError(scene.file + ": " + o.message);
      if (o.overloaded && o.steps == 1)
        throw UsageError(scene.file + ": the initial configuration: " + world->lastReport().problem +
                         "; move the bodies apart (a scene starts with bodies touching, not inside each other)");
      if (metrics) {
        metrics->out() << metricsJson(scene, *world, summary, o, hashes.hashes(), planned).dump(1) << '\n';
        metrics->commit();
      }
      if (traj) traj->commit();
      if (recording) recording->commit();
      if (!opt->quiet) {
        printSummary(scene, *world, summary, o);
        if (traj) std::cout << "wrote     " << *opt->trajectory << "\n";
        if (metrics) std::cout << "wrote     " << *opt->metrics << " (substep rerun " << *opt->metrics << " runs it again)\n";
        if (recording)
          std::cout << "wrote     " << *opt->record << " (" << recording->frames() << " frames, " << std::setprecision(2)
                    << recording->bytes() / 1e6 << " MB)\n";
      }
      if (o.end == RunOutcome::End::Diverged) {
        std::cerr << "substep run: stopped: " << o.message << "; outputs hold the steps before it\n";
        return kExitNonFinite;
      }
      return 0;
    };
  });
}

}  // namespace substep::app
