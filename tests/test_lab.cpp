// The lab library: closed forms and references, metrics of a run (the same for substep and the
// Bullet peer), verdicts, records.
#include "lab/advise.h"
#include "lab/bullet_peer.h"
#include "lab/chart.h"
#include "lab/chart_labels.h"
#include "lab/method.h"
#include "lab/metrics.h"
#include "lab/record.h"
#include "lab/reference.h"
#include "lab/runner.h"
#include "lab/sweep.h"
#include "lab/timeline.h"
#include "lab/verdict.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <set>
#include <unistd.h>

using namespace substep;
using namespace substep::lab;

namespace {

const std::string kScenes = SUBSTEP_SOURCE_DIR "/assets/scenes";

Scene sceneFrom(const std::string& json) { return parseScene(json, "t.json", "."); }

Method method(const std::string& spec) {
  const std::vector<Method> m = parseMethods(spec);
  EXPECT_EQ(m.size(), 1u);
  return m[0];
}

// A run with the scene's own reference prepared.
RunResult runWithReference(const Scene& s, const std::string& spec, double seconds) {
  const PreparedReference ref = prepareReference(s, *s.criteria->reference, seconds);
  RunSetup setup;
  setup.seconds = seconds;
  setup.reference = &ref;
  return runMethod(s, method(spec), setup);
}

constexpr double kPi = 3.14159265358979323846;

}  // namespace

// K and sn against tabulated values (Abramowitz and Stegun, tables 17.1 and 16.1), and the
// identities sn(0) = 0, sn(K) = 1, and sn = sin when k = 0.
TEST(ClosedForms, EllipticIntegralAndJacobiSine) {
  EXPECT_NEAR(ellipticK(0), kPi / 2, 1e-15);
  EXPECT_NEAR(ellipticK(std::sin(kPi / 4)), 1.854074677301372, 1e-13);  // K(m = 1/2)
  EXPECT_NEAR(ellipticK(std::sin(kPi / 12)), 1.598142002112540, 1e-13);  // modular angle 15 degrees
  EXPECT_THROW(ellipticK(1), std::invalid_argument);
  for (double k : {0.0, 0.3, 0.7, 0.99}) {
    EXPECT_NEAR(jacobiSn(0, k), 0, 1e-15) << k;
    EXPECT_NEAR(jacobiSn(ellipticK(k), k), 1, 1e-12) << k;
  }
  EXPECT_NEAR(jacobiSn(0.7, 0), std::sin(0.7), 1e-15);
  EXPECT_NEAR(jacobiSn(0.5, std::sqrt(0.5)), 0.4707504736556573, 1e-13);  // sn(0.5 | m = 0.5)
}

// The pendulum's closed form from the scene: amplitude, small-amplitude and elliptic periods.
TEST(ClosedForms, PendulumPeriodFromTheScene) {
  const Scene small = loadScene(kScenes + "/reference/pendulum_5deg.json");
  const PendulumModel p = pendulumModel(small, *small.criteria->reference);
  EXPECT_NEAR(p.amplitude, 5 * kPi / 180, 1e-9);
  EXPECT_NEAR(p.smallPeriod(), 2 * kPi * std::sqrt(1 / 9.81) * (1 + 0.5e-6), 1e-8);  // point mass: sqrt(L/g)
  EXPECT_NEAR(p.period(), 2.007021914 * (1 + 0.5e-6), 1e-8);  // the bob's given inertia 1e-6 lengthens it by 5e-7
  EXPECT_NEAR(p.angleAt(0), p.amplitude, 1e-12);
  EXPECT_NEAR(p.angleAt(p.period() / 4), 0, 1e-9);
  EXPECT_NEAR(p.angleAt(p.period() / 2), -p.amplitude, 1e-9);
  const Scene large = loadScene(kScenes + "/reference/pendulum_90deg.json");
  EXPECT_NEAR(pendulumModel(large, *large.criteria->reference).period(), 2.367841947 * (1 + 0.5e-6), 1e-8);
  const Scene bar = loadScene(kScenes + "/reference/physical_pendulum.json");
  const PendulumModel b = pendulumModel(bar, *bar.criteria->reference);
  EXPECT_NEAR(b.period(), 1.758364036, 1e-6);  // I about the end = m (L^2 + w^2)/12 + m (L/2)^2
}

// Acceptance: the period at 5 degrees under A1 at h = 1/240 is within 0.5 % of the closed form;
// the other pendulums too, and the swing keeps its energy.
TEST(References, PendulumPeriodsUnderA1) {
  for (const char* file : {"pendulum_5deg", "pendulum_90deg", "physical_pendulum"}) {
    const Scene s = loadScene(kScenes + "/reference/" + file + ".json");
    const RunResult r = runWithReference(s, "a1:h=1/240", 5);
    ASSERT_TRUE(r.finite) << file;
    ASSERT_TRUE(r.metrics.referenceError) << file << ": " << r.metrics.referenceText;
    std::printf("%-18s a1 h=1/240: %s, error %.4f %%, energy drift %.3f %%, trajectory error %.2f mm\n", file,
                r.metrics.referenceText.c_str(), 100 * *r.metrics.referenceError, 100 * r.metrics.energyDrift.value_or(NAN),
                1e3 * r.metrics.trajectoryError.value_or(NAN));
    EXPECT_LT(*r.metrics.referenceError, 0.005) << file;
    EXPECT_EQ(judge(s, r).result, Verdict::Result::Pass) << judge(s, r).figure;
  }
}

// The measured period is the crossings' and fails when the swing is wrong: a run of half a
// period has no period, and a pendulum stepped at a coarse h by A2 misses by more.
TEST(References, PeriodMeasurement) {
  std::vector<double> t, a;
  for (int k = 0; k <= 1000; ++k) {
    t.push_back(k * 0.01);
    a.push_back(std::cos(2 * kPi * t.back() / 2.5 + 0.3));
  }
  EXPECT_NEAR(measuredPeriod(t, a), 2.5, 1e-4);
  t.resize(100), a.resize(100);
  EXPECT_TRUE(std::isnan(measuredPeriod(t, a)));
}


// Free fall has a closed form, and symplectic Euler's error against it is known exactly: after
// time T at step h the position is off by g h T / 2 (h/n under sub-stepping). The metric must
// say so, for substep and for the Bullet peer alike (Bullet's integrator is the same).
TEST(References, FreeFallErrorIsHalfGHT) {
  const Scene s = loadScene(kScenes + "/reference/free_fall.json");
  const double T = 2, g = 9.81;
  for (const char* spec : {"a2:h=1/60", "a2:h=1/120", "a5:n=4:h=1/60", "bullet:h=1/60"}) {
    const RunResult r = runWithReference(s, spec, T);
    ASSERT_TRUE(r.metrics.trajectoryError) << spec;
    const double h = r.settings.dt / (std::string(spec).rfind("a5", 0) == 0 ? 4 : 1);
    EXPECT_NEAR(*r.metrics.trajectoryError, 0.5 * g * h * T, std::string(spec) == "bullet:h=1/60" ? 2e-3 : 1e-9) << spec;
    EXPECT_NEAR(*r.metrics.energyDrift, 0, 0.02) << spec;  // conservative: the drift is measured
  }
}

// Torque-free rotation keeps each body's world angular momentum: exactly about a principal axis;
// about the intermediate axis only with the gyroscopic term, whose flip the "turns" check sees.
TEST(References, TorqueFreeInvariantsAndTheFlip) {
  const Scene spin = sceneFrom(R"({"gravity": [0, 0, 0], "bodies": [{"name": "b", "mass": 1,
      "shape": {"type": "box", "half_extents": [0.05, 0.2, 0.4]}, "angular_velocity": [0, 0, 7]}],
      "criteria": {"conservative": true, "reference": {"type": "torque_free"}}})");
  for (const char* spec : {"a1", "a5", "soft", "bullet"}) {
    const RunResult r = runWithReference(spin, spec, 1);
    const double round = std::string(spec) == "bullet" ? 1e-5 : 1e-9;  // Bullet computes in float
    EXPECT_LT(*r.metrics.referenceError, round) << spec;
    EXPECT_LT(*r.metrics.energyDrift, 2 * round) << spec;
    EXPECT_LT(*r.metrics.angularMomentumDrift, round) << spec;  // a free scene: momentum is measured
  }
  const Scene dz = loadScene(kScenes + "/atlas/dzhanibekov.json");
  const RunResult none = runWithReference(dz, "a5", 3), implicit = runWithReference(dz, "a5:gyro=implicit", 3);
  std::printf("dzhanibekov under a5: gyroscopic none turns %.0f deg, L drift %.1f %%; implicit turns %.0f deg, L drift %.1f %%, "
              "energy drift %+.1f %%\n", *none.metrics.turnedMost * 180 / kPi, 100 * *none.metrics.referenceError,
              *implicit.metrics.turnedMost * 180 / kPi, 100 * *implicit.metrics.referenceError, 100 * *implicit.metrics.energyDriftEnd);
  EXPECT_LT(*none.metrics.turnedMost, 0.1);
  EXPECT_GT(*implicit.metrics.turnedMost, 3.0);  // flipped over
  EXPECT_LT(*implicit.metrics.energyDriftEnd, 0);  // the implicit term dissipates, never gains
  EXPECT_EQ(judge(dz, none).result, Verdict::Result::Fail);
  EXPECT_EQ(judge(dz, implicit).result, Verdict::Result::Pass);
}

// A converged reference is checked by halving h: a coarse one is refused with the numbers.
TEST(References, ConvergedRunIsCheckedByHalvingH) {
  const std::string chain = R"({"bodies": [
      {"name": "pivot", "static": true, "shape": {"type": "sphere", "radius": 0.02}, "position": [0, 3, 0]},
      {"name": "l0", "shape": {"type": "capsule", "radius": 0.05, "half_height": 0.2}, "position": [0.3, 3, 0], "orientation": [0.7071068, 0, 0, 0.7071068], "mass": 1},
      {"name": "l1", "shape": {"type": "capsule", "radius": 0.05, "half_height": 0.2}, "position": [0.9, 3, 0], "orientation": [0.7071068, 0, 0, 0.7071068], "mass": 1}],
    "joints": [{"type": "ball", "bodies": ["pivot", "l0"], "anchor": [0, 3, 0]}, {"type": "ball", "bodies": ["l0", "l1"], "anchor": [0.6, 3, 0]}],
    "criteria": {"reference": {"type": "converged", "method": "@M@", "change": @C@}}})";
  auto with = [&](const std::string& m, const std::string& c) {
    std::string t = chain;
    t.replace(t.find("@M@"), 3, m);
    t.replace(t.find("@C@"), 3, c);
    return sceneFrom(t);
  };
  const Scene coarse = with("a1:h=1/30", "0.001");
  try {
    prepareReference(coarse, *coarse.criteria->reference, 1);
    ADD_FAILURE() << "a coarse reference was accepted";
  } catch (const ReferenceError& e) {
    EXPECT_NE(std::string(e.what()).find("is not converged: halving h to 1/60 moved the trajectory by"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("the scene allows 0.10 %"), std::string::npos) << e.what();
  }
  const Scene fine = with("a1:h=1/960", "0.01");
  const PreparedReference ref = prepareReference(fine, *fine.criteria->reference, 1);
  ASSERT_TRUE(ref.converged);
  EXPECT_LT(ref.converged->change, 0.01 * ref.converged->motion);
  RunSetup setup;
  setup.seconds = 1;
  setup.reference = &ref;
  const RunResult a1 = runMethod(fine, method("a1:h=1/240"), setup), a2 = runMethod(fine, method("a2:m=4:h=1/60"), setup);
  std::printf("double pendulum, 1 s against a1 at h = 1/1920: a1 h=1/240 %.2f mm, a2 m=4 h=1/60 %.1f mm\n",
              1e3 * *a1.metrics.trajectoryError, 1e3 * *a2.metrics.trajectoryError);
  EXPECT_LT(*a1.metrics.trajectoryError, *a2.metrics.trajectoryError);
  EXPECT_LT(*a1.metrics.trajectoryErrorRms, *a1.metrics.trajectoryError + 1e-15);
}

// One run, measured the same way for substep and for the Bullet peer: a box dropped 1 m onto the
// ground falls 1 m, lands at about 4.4 m/s and comes to rest. Bullet, without speculative
// contacts, sinks 3 cm at the impact; ours stop within 2 cm.
TEST(Metrics, ADropMeasuredForBothEngines) {
  const Scene s = sceneFrom(R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [5, 0.5, 5]}, "position": [0, -0.5, 0]},
      {"name": "box", "shape": {"type": "box", "half_extents": [0.5, 0.5, 0.5]}, "position": [0, 1.5, 0], "mass": 1}],
      "criteria": {"tolerance": 0.5, "pass": {"penetration": 0.05, "jitter": 0.05}}})");
  for (const char* spec : {"a2", "a5", "soft", "bullet"}) {
    RunSetup setup;
    setup.seconds = 2;
    setup.repeat = 3;
    const RunResult r = runMethod(s, method(spec), setup);
    const Metrics& m = r.metrics;
    EXPECT_TRUE(r.finite) << spec;
    EXPECT_EQ(r.stepsDone, 120) << spec;
    EXPECT_NEAR(m.displacementMax, 1.0, 0.04) << spec;
    EXPECT_NEAR(m.speedMax, std::sqrt(2 * 9.81 * 1.0), 0.3) << spec;
    ASSERT_TRUE(m.collapseTime) << spec;  // it moved more than the scene's 0.5 m tolerance while falling
    EXPECT_NEAR(*m.collapseTime, std::sqrt(2 * 0.5 / 9.81), 0.03) << spec;
    EXPECT_GT(m.penetrationMax, 0) << spec;
    EXPECT_LT(m.penetrationMax, std::string(spec) == "bullet" ? 0.04 : 0.02) << spec;
    EXPECT_LE(m.penetrationRms, m.penetrationMax) << spec;
    EXPECT_LT(m.jitter, 0.05) << spec;
    EXPECT_EQ(m.joints, 0);
    EXPECT_FALSE(metricValue(m, "joint_error"));  // no joints: not measured
    EXPECT_FALSE(m.energyDrift);                  // not conservative: not measured
    EXPECT_EQ(r.cost.repeats.size(), 3u) << spec;
    EXPECT_GT(r.cost.msPerStep, 0) << spec;
    EXPECT_EQ(r.cost.stages.has_value(), std::string(spec) != "bullet") << spec;  // Bullet's stages are its own
    EXPECT_EQ(judge(s, r).result, Verdict::Result::Pass) << spec << ": " << judge(s, r).figure;
  }
}

// Joints by kind, angular errors and limits, over the run.
TEST(Metrics, JointErrorsByKind) {
  const Scene s = loadScene(kScenes + "/ragdoll.json");
  RunSetup setup;
  setup.seconds = 1;
  const RunResult r = runMethod(s, method("a5"), setup);
  const Metrics& m = r.metrics;
  ASSERT_EQ(m.byKind.count("cone_twist"), 1u);
  ASSERT_EQ(m.byKind.count("hinge"), 1u);
  double worst = 0;
  for (const auto& [kind, k] : m.byKind) {
    EXPECT_LE(k.rms, k.max) << kind;
    EXPECT_GT(k.samples, 0) << kind;
    worst = std::max(worst, k.max);
  }
  EXPECT_DOUBLE_EQ(worst, m.jointErrorMax);
  EXPECT_GT(m.byKind.at("hinge").angleMax, 0);  // hinge axes apart, measured
  EXPECT_EQ(m.byKind.at("cone_twist").angleMax, 0);  // a cone-twist holds no angle: its limits do
  EXPECT_GE(m.limitExcess.max(), m.limitExcess.hinge);
  EXPECT_EQ(*metricValue(m, "limit_excess"), m.limitExcess.max());
}

// A method that cannot run a scene is a result that says so, not an error.
TEST(Runner, RefusedAndDivergedRunsAreResults) {
  const Scene shapes = loadScene(kScenes + "/shapes.json");  // meshes: no Bullet peer
  RunSetup setup;
  setup.seconds = 0.5;
  const RunResult b = runMethod(shapes, method("bullet"), setup);
  EXPECT_TRUE(b.refused);
  EXPECT_NE(b.stopped.find("no Bullet peer for this scene"), std::string::npos) << b.stopped;
  EXPECT_EQ(judge(shapes, b).result, Verdict::Result::Refused);
  // The explicit gyroscopic term gains energy every step: at a large omega h the spin explodes,
  // and the run stops where the failure watch says it diverged.
  const Scene spin = sceneFrom(R"({"gravity": [0, 0, 0], "bodies": [{"name": "b", "mass": 1,
      "shape": {"type": "box", "half_extents": [0.05, 0.2, 0.4]}, "angular_velocity": [1, 60, 0]}], "criteria": {"pass": {"speed": 1000}}})");
  setup.seconds = 20;
  const RunResult d = runMethod(spin, method("a2:gyro=explicit"), setup);
  EXPECT_TRUE(d.diverged);
  EXPECT_LT(d.stepsDone, d.steps);
  EXPECT_NE(d.stopped.find("the simulation diverged at step "), std::string::npos) << d.stopped;
  EXPECT_EQ(judge(spin, d).result, Verdict::Result::Fail);
  EXPECT_NE(judge(spin, d).figure.find("diverged at"), std::string::npos);
  // A scene that states no check gives no verdict, whatever became of the run.
  Scene bare = spin;
  bare.criteria->pass.clear();
  EXPECT_EQ(judge(bare, d).result, Verdict::Result::NoCriteria);
  // Settings that do not resolve are an error before any run.
  EXPECT_THROW(runMethod(shapes, method("a2:preset=4-medium"), RunSetup{}), std::invalid_argument);
}

// The settings a method runs with: its own, over the scene's criteria "with", over the time step;
// never the rest of the scene's solver block.
TEST(Methods, SettingsComeFromTheMethodTheWithBlockAndTheStep) {
  const Scene p = loadScene(kScenes + "/pyramid.json");  // its solver block: a5, kappa 0.85, tau 0, warm
  const SolverSettings s = methodSettings(method("a5:n=8"), p);
  EXPECT_EQ(s.substeps, 8);
  EXPECT_EQ(s.kappa, 1.0);
  EXPECT_FALSE(s.warmStart);
  EXPECT_DOUBLE_EQ(s.dt, 1.0 / 60);
  EXPECT_DOUBLE_EQ(methodSettings(method("a5"), p, 0.005).dt, 0.005);
  EXPECT_DOUBLE_EQ(methodSettings(method("a5:h=1/30"), p, 0.005).dt, 1.0 / 30);  // the method's own wins
  const Scene dz = loadScene(kScenes + "/atlas/dzhanibekov_implicit.json");
  EXPECT_EQ(methodSettings(method("a2"), dz).gyroscopic, Gyroscopic::Implicit);
  EXPECT_EQ(methodSettings(method("a2:gyro=none"), dz).gyroscopic, Gyroscopic::None);
  const BulletSettings b = bulletSettings(method("bullet:it=20"), p);
  EXPECT_EQ(b.iterations, 20);
  EXPECT_TRUE(b.gyroscopic);  // Bullet's own default
  EXPECT_FALSE(bulletSettings(method("bullet:gyro=none"), p).gyroscopic);
  EXPECT_EQ(method("bullet:it=20").family(), "bullet");
  EXPECT_EQ(method("a5:n=8").family(), "a5");
  EXPECT_EQ(stepText(1.0 / 120), "1/120");
  EXPECT_EQ(stepText(0.003), "0.003");
}

// A record holds every setting (typed), every metric, the verdict and the commit.
TEST(Records, OneRecordPerRun) {
  const Scene s = loadScene(kScenes + "/atlas/projectile_wall.json");
  RunSetup setup;
  setup.seconds = 0.5;
  const RunResult r = runMethod(s, method("a5:n=2"), setup);
  const nlohmann::json j = recordJson(s, r, 0.5, 1, SweepPlace{"abc", 3, 10});
  EXPECT_EQ(j["key"], "projectile_wall | a5:n=2 | h=1/60 | 0.5 s");
  EXPECT_EQ(j["settings"]["substeps"], 2);  // an integer
  EXPECT_EQ(j["settings"]["warm_start"], false);
  EXPECT_EQ(j["h"], "1/60");
  for (const SettingSpec& spec : settingTable()) EXPECT_EQ(j["settings"].contains(spec.key), spec.resolved()) << spec.key;
  // And what re-runs it (lab/rerun.h).
  for (const char* k : {"scene_file", "scene_path", "scene_hash", "engine", "steps", "steps_done", "commit", "threads",
                        "state_hash", "state_hashes"})
    EXPECT_TRUE(j.contains(k)) << k;
  for (const char* k : {"penetration_max_m", "penetration_rms_m", "joint_error_by_kind", "limit_excess_rad", "energy_drift",
                        "jitter_mps", "displacement_max_m", "collapse_time_s", "trajectory_error_m", "failure"})
    EXPECT_TRUE(j["metrics"].contains(k)) << k;
  EXPECT_TRUE(j["cost"]["stages_ms_per_step"].contains("s3"));
  EXPECT_EQ(j["verdict"]["result"], "pass");
  EXPECT_EQ(j["error"]["metric"], "penetration");
  EXPECT_EQ(j["sweep"]["index"], 3);
  EXPECT_FALSE(j["commit"].get<std::string>().empty());
  EXPECT_EQ(*recordValue(j, "penetration"), r.metrics.penetrationMax);
  EXPECT_FALSE(recordValue(j, "joint_error"));
  EXPECT_EQ(errorMetric(loadScene(kScenes + "/chain.json")), "joint_error");
  EXPECT_EQ(errorMetric(loadScene(kScenes + "/stack.json")), "penetration");
  EXPECT_EQ(errorMetric(loadScene(kScenes + "/reference/free_fall.json")), "trajectory_error");
}

// What a scene's criteria state: checks to pass (one test serves the verdict and advise) and an
// error measure (the stated one serves errorMetric and advise's --max-error).
TEST(Verdicts, TheChecksAndTheErrorASceneStates) {
  auto scene = [](const std::string& criteria) {
    return sceneFrom(R"({"bodies": [
        {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [5, 0.5, 5]}, "position": [0, -0.5, 0]},
        {"name": "box", "shape": {"type": "box", "half_extents": [0.5, 0.5, 0.5]}, "position": [0, 0.5, 0], "mass": 1}])" +
                     (criteria.empty() ? "" : ", \"criteria\": " + criteria) + "}");
  };
  const Scene bare = scene("");
  EXPECT_FALSE(statedErrorMetric(bare));
  EXPECT_EQ(errorMetric(bare), "penetration");
  const Scene errorOnly = scene(R"({"error": "jitter", "rest": ["box"]})");
  EXPECT_FALSE(hasChecks(*errorOnly.criteria));
  EXPECT_EQ(statedErrorMetric(errorOnly), "jitter");
  RunSetup setup;
  setup.seconds = 0.1;
  EXPECT_EQ(judge(errorOnly, runMethod(errorOnly, method("a5"), setup)).result, Verdict::Result::NoCriteria);
  const Scene torqueFree = scene(R"({"reference": {"type": "torque_free"}})");
  EXPECT_FALSE(hasChecks(*torqueFree.criteria));
  EXPECT_EQ(statedErrorMetric(torqueFree), "reference_error");
  for (const char* pass : {R"({"displacement": 0.01})", R"({"moving": {"bodies": "box", "at_least": 0.1}})",
                           R"({"stay_in": {"body": "box", "min": [-1, -1, -1], "max": [1, 1, 1]}})",
                           R"({"turns": {"body": "box", "axis": [0, 1, 0], "at_least": 1}})"}) {
    const Scene s = scene(std::string(R"({"pass": )") + pass + "}");
    EXPECT_TRUE(hasChecks(*s.criteria)) << pass;
    EXPECT_NE(judge(s, runMethod(s, method("a5"), setup)).result, Verdict::Result::NoCriteria) << pass;
  }
  EXPECT_EQ(statedErrorMetric(scene(R"({"pass": {"displacement": 0.01}})")), "displacement");
}

TEST(Charts, ParetoFrontAndSlope) {
  const std::vector<std::pair<double, double>> pts = {{1, 10}, {2, 5}, {3, 6}, {4, 1}, {0.5, 20}, {5, 1}};
  EXPECT_EQ(paretoFront(pts), (std::vector<size_t>{4, 0, 1, 3}));
  EXPECT_NEAR(logSlope({{0.1, 0.02}, {0.05, 0.005}, {0.025, 0.00125}}), 2.0, 1e-12);
  EXPECT_TRUE(std::isnan(logSlope({{0.1, 0.02}})));
}

namespace {

nlohmann::json fakeRow(const std::string& scene, const std::string& method, const std::string& family, int n, int m,
                       double dt, double error, double msPerStep) {
  return {{"key", scene + method + std::to_string(dt)}, {"scene", scene}, {"method", method}, {"family", family},
          {"refused", false}, {"finite", true}, {"diverged", false},
          {"h", stepText(dt)}, {"settings", {{"dt", dt}, {"substeps", n}, {"iterations", m}, {"algorithm", family}}},
          {"cost", {{"ms_per_step", msPerStep}, {"ms_per_second", msPerStep / dt}}},
          {"values", {{"joint_error", error}}},
          {"error", {{"metric", "joint_error"}, {"label", "max joint error"}, {"unit", "m"}, {"value", error}}}};
}

}  // namespace

// What each chart is made of, from records: the Pareto front, sub-steps against iterations at
// equal work, A3/A4/A5, and the convergence order with its slope.
TEST(Charts, EveryChartFromTheRecordsItNeeds) {
  std::vector<nlohmann::json> rows;
  for (int k : {1, 2, 4, 8}) {
    rows.push_back(fakeRow("c", "a2:m=" + std::to_string(k), "a2", 1, k, 1.0 / 60, 0.2 / k, 0.01 * k));
    for (const char* f : {"a3", "a4", "a5"})
      rows.push_back(fakeRow("c", std::string(f) + ":n=" + std::to_string(k) + ":m=1", f, k, 1, 1.0 / 60, 0.05 / (k * k), 0.012 * k));
  }
  for (int d : {30, 60, 120}) rows.push_back(fakeRow("c", "a1:h=1/" + std::to_string(d), "a1", 1, 10, 1.0 / d, 0.3 / d, 0.5));
  const std::vector<Chart> charts = makeCharts(rows, ChartOptions{});
  std::vector<std::string> names;
  for (const Chart& c : charts) names.push_back(c.name);
  EXPECT_EQ(names, (std::vector<std::string>{"c-pareto", "c-substeps", "c-havok", "c-convergence", "c-speed"}));
  EXPECT_NE(charts[0].script.find("title \"a5\""), std::string::npos);
  EXPECT_NE(charts[0].script.find("Pareto front"), std::string::npos);
  EXPECT_NE(charts[0].script.find("set ylabel \"max joint error [m]\""), std::string::npos);
  EXPECT_NE(charts[0].script.find("cost per simulated second [ms]"), std::string::npos);
  EXPECT_NE(charts[1].script.find("a2: 1 step of n iterations"), std::string::npos);
  EXPECT_NE(charts[1].script.find("a5: n sub-steps of 1 iteration"), std::string::npos);
  EXPECT_NE(charts[3].script.find("a1 (slope 1.00)"), std::string::npos) << charts[3].script;
  const std::string png = chartScript(charts[0], "png", "o'ut.png", "d.dat", ChartOptions{});
  EXPECT_NE(png.find("set terminal pngcairo size 960,600"), std::string::npos);
  EXPECT_NE(png.find("set output 'o''ut.png'"), std::string::npos);
  EXPECT_EQ(png.find('@'), std::string::npos);
  // Only what the rows hold: a lone method gives the Pareto chart alone.
  EXPECT_EQ(makeCharts({rows[0]}, ChartOptions{}).size(), 1u);
  // Labels name h only where it is not the chart's common step, and the title says so.
  EXPECT_NE(charts[0].title.find("(h = 1/60 unless labelled)"), std::string::npos) << charts[0].title;
  EXPECT_NE(charts[0].script.find("\"h=1/30\" at screen"), std::string::npos) << charts[0].script;
  EXPECT_EQ(charts[0].script.find("m=4 h=1/60"), std::string::npos) << charts[0].script;
}

// A3/A4/A5 at one n each (the atlas's presets) is no chart against n; zero errors are drawn at a
// floor on log axes, labelled 0 and said so; the front's points are ringed.
TEST(Charts, OneNIsNoLineAndZeroIsLabelled) {
  std::vector<nlohmann::json> rows;
  for (const char* f : {"a3", "a4", "a5"}) rows.push_back(fakeRow("z", std::string(f) + ":n=4", f, 4, 1, 1.0 / 60, 0, 0.01));
  rows.push_back(fakeRow("z", "a2:m=4", "a2", 1, 4, 1.0 / 60, 0.2, 0.004));
  const std::vector<Chart> charts = makeCharts(rows, ChartOptions{});
  ASSERT_EQ(charts.size(), 1u) << charts.back().name;
  EXPECT_EQ(charts[0].name, "z-pareto");
  EXPECT_NE(charts[0].script.find("\"n=4 (0)\" at screen"), std::string::npos) << charts[0].script;
  EXPECT_NE(charts[0].script.find("a zero error is drawn at 0.02 (a tenth of the least other)"), std::string::npos)
      << charts[0].script;
  EXPECT_NE(charts[0].script.find("with points pt 6"), std::string::npos);  // the ring on the front
  // A second n for one family makes the chart.
  rows.push_back(fakeRow("z", "a5:n=8", "a5", 8, 1, 1.0 / 60, 0, 0.02));
  EXPECT_EQ(makeCharts(rows, ChartOptions{}).size(), 2u);
}

// A zero error is listed under the chart as 0, not as the floor it is drawn at; a zero cost (a run
// quicker than the clock) is drawn at a floor of the log x axis (a tenth of the least other),
// labelled "cost 0", listed as 0 ms, and the chart and its notes say where. Crowded at one point
// so that some are listed.
TEST(Charts, ZerosAreDrawnAtTheFloorAndListedAsZero) {
  std::vector<nlohmann::json> rows;
  for (int k = 0; k < 8; ++k)
    rows.push_back(fakeRow("z", "a5:n=" + std::to_string(k + 1) + ":m=4", "a5", k + 1, 4, 1.0 / 60, 0, 0.05));
  rows.push_back(fakeRow("z", "a2:m=4", "a2", 1, 4, 1.0 / 60, 0.2, 0.004));
  rows.push_back(fakeRow("z", "a2:m=8", "a2", 1, 8, 1.0 / 60, 0.1, 0));
  const ChartOptions o;
  const std::vector<Chart> charts = makeCharts(rows, o);
  ASSERT_FALSE(charts.empty());
  const Chart& c = charts[0];
  ASSERT_EQ(c.name, "z-pareto");
  // The floors: errors at 0.01 (a tenth of 0.1), costs at 0.024 ms (a tenth of 0.004 * 60).
  EXPECT_NE(c.script.find("a zero error is drawn at 0.01 (a tenth of the least other)"), std::string::npos) << c.script;
  EXPECT_NE(c.script.find("a zero cost is drawn at 0.024 ms (a tenth of the least other)"), std::string::npos) << c.script;
  EXPECT_NE(std::find(c.notes.begin(), c.notes.end(), "a zero cost is drawn at 0.024 ms (a tenth of the least other)"), c.notes.end());
  EXPECT_NE(c.data.find("0.024 0.1\n"), std::string::npos) << c.data;  // the zero-cost point, at the floor
  // A finite x range with the floor in it.
  std::smatch range;
  ASSERT_TRUE(std::regex_search(c.script, range, std::regex(R"(set xrange \[([^:]+):([^\]]+)\])"))) << c.script;
  const double x0 = std::stod(range[1]), x1 = std::stod(range[2]);
  EXPECT_TRUE(std::isfinite(x0) && x0 > 0 && x0 < 0.024 && x1 > 3) << range[0];
  EXPECT_TRUE(c.script.find("\"m=8 (cost 0)\" at screen") != std::string::npos ||
              c.script.find("  a2 m=8 (cost 0): (no tag) 0 ms, 10.0 cm") != std::string::npos ||
              c.script.find("  a2 m=8 (cost 0): 0 ms, 10.0 cm") != std::string::npos)
      << c.script;
  // The zero errors in the list: "0", never the floor's 1.00 cm.
  int listed = 0;
  for (int k = 0; k < 8; ++k) {
    const std::string entry = "  a5 n=" + std::to_string(k + 1) + " m=4 (0): ";
    const size_t at = c.script.find(entry);
    if (at == std::string::npos) continue;
    ++listed;
    const std::string line = c.script.substr(at, c.script.find('"', at) - at);
    EXPECT_EQ(line.substr(line.size() - 3), ", 0") << line;
  }
  EXPECT_GE(listed, 3);  // of the eight at one point, most find no room
  EXPECT_EQ(c.script.find("1.00 cm\""), std::string::npos) << c.script;
}

// Labels placed around clustered points: none overlaps another, covers a point or leaves the
// area; what did not fit is numbered, in order.
TEST(ChartLabels, ClearOfEachOtherAndOfThePoints) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> near(380, 460);  // 60 points within 80 px: most cannot have a label
  std::vector<LabelRequest> requests;
  std::vector<Box> points;
  for (int i = 0; i < 60; ++i) {
    const double x = near(rng), y = near(rng) - 150;
    requests.push_back({x, y, "a5 n=" + std::to_string(i) + " m=1"});
    points.push_back({x - 6, y - 6, x + 6, y + 6});
  }
  const Box area{100, 40, 860, 540};
  const std::vector<LabelPlacement> placed = placeLabels(requests, points, area);
  ASSERT_EQ(placed.size(), requests.size());
  std::vector<Box> boxes;
  int texts = 0, number = 0;
  for (size_t i = 0; i < placed.size(); ++i) {
    const LabelPlacement& p = placed[i];
    if (p.kind == LabelPlacement::Kind::Text) ++texts;
    if (p.kind != LabelPlacement::Kind::Text) {
      EXPECT_EQ(p.number, ++number) << i;  // every other one is listed
    }
    if (p.kind == LabelPlacement::Kind::None) continue;
    const std::string text = p.kind == LabelPlacement::Kind::Text ? requests[i].text : std::to_string(p.number);
    const Box b = labelBox(text, p.x, p.y);
    EXPECT_TRUE(b.inside(area)) << i;
    for (const Box& q : points) EXPECT_FALSE(b.overlaps(q)) << i;
    for (const Box& q : boxes) EXPECT_FALSE(b.overlaps(q)) << i;
    boxes.push_back(b);
  }
  EXPECT_GT(texts, 5);      // the first ones get their label
  EXPECT_LT(texts, 60);     // and not all fit: the list is tested
  EXPECT_GT(boxes.size(), static_cast<size_t>(texts));  // some got a tag
}

// The Pareto chart of a crowded sweep (eight methods at one point, as chain.json gave, and a
// seeded cluster): the labels the script places do not overlap, and every point is on the chart
// by its label or in the list under it; a diverged run is listed or labelled with its family.
TEST(Charts, LabelsNeverOverlapAndTheRestAreListed) {
  std::vector<nlohmann::json> rows;
  std::vector<std::string> labels;
  for (int k = 0; k < 8; ++k) {
    rows.push_back(fakeRow("c", "a5:n=" + std::to_string(k + 1) + ":m=4", "a5", k + 1, 4, 1.0 / 60, 0.01, 0.05));
    labels.push_back("n=" + std::to_string(k + 1) + " m=4");
  }
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  for (int k = 0; k < 30; ++k) {
    const std::string fam = k % 2 ? "a3" : "a4";
    rows.push_back(fakeRow("c", fam + ":n=" + std::to_string(k + 10) + ":m=2", fam, k + 10, 2, 1.0 / 60, 0.005 * (1 + u(rng)),
                           0.04 * (1 + u(rng))));
    labels.push_back("n=" + std::to_string(k + 10) + " m=2");
  }
  nlohmann::json bad = fakeRow("c", "a2:m=3", "a2", 1, 3, 1.0 / 60, NAN, 0.02);
  bad["diverged"] = true;
  rows.push_back(bad);
  const ChartOptions o;
  const std::vector<Chart> charts = makeCharts(rows, o);
  ASSERT_FALSE(charts.empty());
  const Chart& c = charts[0];
  ASSERT_EQ(c.name, "c-pareto");
  EXPECT_GT(c.extraHeight, 0);
  const double W = o.width, H = o.height + c.extraHeight;
  const std::regex label(R"re(set label \d+ "([^"]*)" at screen ([-0-9.e]+), screen ([-0-9.e]+) left font ',8' tc)re");
  std::vector<Box> boxes;
  std::set<std::string> onChart;
  std::string all = c.script;
  for (std::sregex_iterator it(all.begin(), all.end(), label), end; it != end; ++it) {
    const std::string text = (*it)[1];
    const Box b = labelBox(text, std::stod((*it)[2]) * W, (1 - std::stod((*it)[3])) * H);
    for (const Box& q : boxes) EXPECT_FALSE(b.overlaps(q)) << text;
    boxes.push_back(b);
    onChart.insert(text);
  }
  EXPECT_GT(onChart.size(), 5u);
  int listed = 0;
  for (size_t i = 0; i < labels.size(); ++i) {
    const std::string fam = rows[i]["family"].get<std::string>();
    const bool inList = c.script.find("  " + fam + " " + labels[i] + ": ") != std::string::npos;
    listed += inList;
    EXPECT_TRUE(onChart.count(labels[i]) || inList) << labels[i];
  }
  EXPECT_GE(listed, 6);  // of the eight at one point, at most two find room
  EXPECT_TRUE(onChart.count("a2 m=3") || c.script.find("  a2 m=3: 1") != std::string::npos) << c.script;
  EXPECT_NE(c.script.find("title 'diverged'"), std::string::npos);
  EXPECT_NE(chartScript(c, "png", "o.png", "d.dat", o).find("size 960," + std::to_string(600 + c.extraHeight)), std::string::npos);
}

// A failed comparison prints the digits that show why: never "1.00 cm > 1.00 cm".
TEST(Advice, ComparisonsShowTheDigitsThatDiffer) {
  EXPECT_EQ(comparisonText("joint_error", 0.01004, ">", 0.01), "max joint error 1.004 cm > 1.000 cm");
  EXPECT_EQ(comparisonText("joint_error", 0.0100004, ">", 0.01), "max joint error 1.00004 cm > 1.00000 cm");
  EXPECT_EQ(comparisonText("joint_error", 0.0131, ">", 0.01), "max joint error 1.31 cm > 1.00 cm");  // no more than needed
  EXPECT_EQ(comparisonText("joint_error", 0.01, "<=", 0.01), "max joint error 1.00 cm <= 1.00 cm");  // equal is equal
  EXPECT_EQ(checkAtMost("penetration", 0.0050004, 0.005).text, "max penetration 5.0004 mm > 5.0000 mm");
}

// Sweep specs, plans, shards, truncated outputs and merging.
TEST(Sweeps, SpecPlanShardsAndMerge) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("substep_test_lab_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return (dir / name).string();
  };
  auto error = [&](const std::string& text) {
    try {
      readSweepSpec(write("bad.json", text));
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(error(R"({"scenes": ["chain"], "methods": ["a9"]})").find("methods[0]: \"a9\": unknown algorithm"), std::string::npos);
  EXPECT_NE(error(R"({"scenes": ["chain"], "methods": "a2", "dt": ["1/0"]})").find("dt[0]: expected a number in [1e-6, 1]"), std::string::npos);
  EXPECT_NE(error(R"({"scenes": ["chain"], "methods": "a2", "repat": 2})").find("unknown key \"repat\""), std::string::npos);
  EXPECT_NE(error(R"({"methods": "a2"})").find("missing required field \"scenes\""), std::string::npos);
  EXPECT_NE(error("[1,").find("not JSON"), std::string::npos);
  const SweepSpec spec = readSweepSpec(write("ok.json", R"({"scenes": ["chain"], "methods": ["a2:m=4|10", "a1:h=1/240"],
      "dt": ["1/60", 0.01], "repeat": 2, "seconds": 1.5})"));
  EXPECT_EQ(spec.dts.size(), 2u);
  EXPECT_DOUBLE_EQ(spec.dts[0], 1.0 / 60);
  std::vector<Scene> scenes = {loadScene(kScenes + "/chain.json"), loadScene(kScenes + "/stack.json")};
  const SweepPlan plan = planSweep(spec, scenes);
  // 2 scenes x (2 a2 methods x 2 steps + a1 at its own h once) = 10.
  ASSERT_EQ(plan.runs.size(), 10u);
  // The chain states a converged reference: its keys say which.
  EXPECT_EQ(plan.runs[0].key, "chain | a2:m=4 | h=1/60 | 1.5 s | against converged a3:n=4:m=8:h=1/240");
  EXPECT_EQ(plan.runs[1].key, "chain | a2:m=4 | h=1/100 | 1.5 s | against converged a3:n=4:m=8:h=1/240");
  EXPECT_EQ(plan.runs[4].key, "chain | a1:h=1/240 | h=1/240 | 1.5 s | against converged a3:n=4:m=8:h=1/240");
  EXPECT_EQ(plan.runs[5].key, "stack | a2:m=4 | h=1/60 | 1.5 s");
  EXPECT_EQ(planSweep(spec, scenes).id, plan.id);
  SweepSpec other = spec;
  other.repeat = 5;  // repeats do not change what runs
  EXPECT_EQ(planSweep(other, scenes).id, plan.id);
  other.seconds = 2;
  EXPECT_NE(planSweep(other, scenes).id, plan.id);
  // Shards: every run in exactly one.
  for (long long k = 0; k < 10; ++k) {
    int in = 0;
    for (int i = 1; i <= 3; ++i) in += Shard{i, 3}.has(k);
    EXPECT_EQ(in, 1);
  }
  EXPECT_EQ(parseShard("2/4").index, 2);
  for (const char* bad : {"0/4", "5/4", "2", "a/b", "1/0", "-1/2", "1/2/3"}) EXPECT_THROW(parseShard(bad), std::invalid_argument) << bad;
  // A last line cut short is left out and reported; any other bad line is an error.
  bool truncated = false;
  auto rows = readRows(write("r.jsonl", "{\"key\": \"a\"}\n{\"key\": \"b\"}\n{\"key\": \"c\", \"cost\""), &truncated);
  EXPECT_TRUE(truncated);
  EXPECT_EQ(rows.size(), 2u);
  EXPECT_THROW(readRows(write("r2.jsonl", "{\"key\": \"a\"}\nnot json\n{\"key\": \"b\"}\n")), std::runtime_error);
  EXPECT_THROW(readRows(write("r3.jsonl", "{\"nokey\": 1}\n")), std::runtime_error);
  // Merging: duplicates kept once, gaps named per plan.
  auto row = [](const std::string& key, long long index) {
    return nlohmann::json{{"key", key}, {"sweep", {{"plan", "p"}, {"index", index}, {"runs", 5}}}};
  };
  const MergeResult m = mergeRows({{row("k0", 0), row("k2", 2)}, {row("k1", 1), row("k2", 2)}});
  EXPECT_EQ(m.rows.size(), 3u);
  EXPECT_EQ(m.rows[1]["key"], "k1");  // in plan order
  EXPECT_EQ(m.duplicates, std::vector<std::string>{"k2"});
  ASSERT_EQ(m.gaps.size(), 1u);
  EXPECT_EQ(m.gaps[0], "plan p: 2 of 5 runs missing (4, 5)");
  std::filesystem::remove_all(dir);
}

TEST(Advice, QuantitiesWithUnits) {
  EXPECT_DOUBLE_EQ(parseQuantity("1cm", "m"), 0.01);
  EXPECT_DOUBLE_EQ(parseQuantity("5 mm", "m"), 0.005);
  EXPECT_DOUBLE_EQ(parseQuantity("0.02", "m"), 0.02);
  EXPECT_DOUBLE_EQ(parseQuantity("60s", "s"), 60);
  EXPECT_DOUBLE_EQ(parseQuantity("2min", "s"), 120);
  EXPECT_DOUBLE_EQ(parseQuantity("2%", ""), 0.02);
  EXPECT_NEAR(parseQuantity("90deg", "rad"), kPi / 2, 1e-15);
  for (const char* bad : {"", "cm", "1 parsec", "-1cm", "0", "nan", "1e999m", "5s"})
    EXPECT_THROW(parseQuantity(bad, "m"), std::invalid_argument) << bad;
}

// The search finds the cheapest candidate that meets the target, by measured cost, and says when
// none does. The 10-link pendulum chain released horizontal: its joints open 28 cm under A2 at
// one iteration, 7 cm at two, 3.4 cm once converged (20 iterations or 1000), 2.2 cm under A5 at
// n = 8, m = 8. Candidates far beyond the cheapest that met the target are not run.
TEST(Advice, CheapestThatMeetsTheTarget) {
  const Scene s = loadScene(kScenes + "/pendulum_chain.json");
  AdviseOptions o;
  o.seconds = 2;
  o.targets = {Target{"joint_error", 0.05}};
  o.candidates = parseMethods("a2:m=1|2|20|1000:h=1/60,a5:n=8:m=8");
  // A5 at n = 8, m = 8 costs about twice A2 at m = 20 here: one timed run each was reversed once
  // in CI, under the other tests' load; the median of five is not.
  o.repeat = 5;
  const Advice a = advise(s, o);
  ASSERT_GE(a.best, 0);
  const Candidate& best = a.tried[static_cast<size_t>(a.best)];
  EXPECT_TRUE(best.meets);
  EXPECT_LE(*metricValue(best.run.metrics, "joint_error"), 0.05);
  EXPECT_EQ(best.method.text, "a2:m=20:h=1/60");
  for (const Candidate& c : a.tried) {
    if (c.meets) {
      EXPECT_LE(best.run.msPerSecond(), c.run.msPerSecond()) << c.method.text;
    } else {
      EXPECT_FALSE(c.missed.empty()) << c.method.text;
    }
    EXPECT_NE(c.method.text, "a2:m=1000:h=1/60");  // 15 times the work of the cheapest that met it
  }
  EXPECT_GE(a.runnerUp, 0);
  EXPECT_EQ(a.tried.front().method.text, "a2:m=1:h=1/60");  // cheapest estimate first
  EXPECT_FALSE(a.tried.front().run.stoppedEarly.empty());  // and stopped once it missed
  o.targets = {Target{"joint_error", 1e-9}};
  const Advice none = advise(s, o);
  EXPECT_EQ(none.best, -1);
  EXPECT_GE(none.closest, 0);
  EXPECT_EQ(estimatedWork(method("a5:n=4:m=1"), s) < estimatedWork(method("a5:n=8:m=1"), s), true);
  EXPECT_GT(defaultCandidates().size(), 500u);
}

// The library refuses what the command refuses: a "criteria" target on a scene that states no
// checks (no criteria; criteria with an error measure only), which it would otherwise read from
// criteria that are not there, and no target at all.
TEST(Advice, ACriteriaTargetNeedsTheScenesChecks) {
  AdviseOptions o;
  o.seconds = 0.1;
  o.candidates = parseMethods("a5");
  o.repeat = 1;
  o.targets = {Target{"criteria", 0}};
  for (const char* name : {"stack.json", "pyramid.json"}) {
    const Scene s = loadScene(kScenes + "/" + name);
    try {
      advise(s, o);
      ADD_FAILURE() << name << ": no error";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(std::string(name) + ", which states no criteria.pass (nor moving, stay_in, turns)"),
                std::string::npos)
          << e.what();
    }
  }
  const Scene wall = loadScene(kScenes + "/atlas/projectile_wall.json");
  EXPECT_EQ(advise(wall, o).tried.size(), 1u);
  o.targets.clear();
  EXPECT_THROW(advise(wall, o), std::invalid_argument);
}

// Wall time spent before the search (finding a reference) is part of its budget: with all of it
// spent, nothing runs and every candidate is left, said as the budget's.
TEST(Advice, TimeSpentBeforeTheSearchCountsAgainstTheBudget) {
  const Scene wall = loadScene(kScenes + "/atlas/projectile_wall.json");
  AdviseOptions o;
  o.seconds = 0.2;
  o.candidates = parseMethods("a5,a2:m=4");
  o.repeat = 1;
  o.targets = {Target{"penetration", 0.05}};
  o.timeBudget = 30;
  o.budgetUsed = 30;
  const Advice spent = advise(wall, o);
  EXPECT_TRUE(spent.tried.empty());
  EXPECT_TRUE(spent.budgetSpent);
  EXPECT_EQ(spent.notRun.size(), 2u);
  o.budgetUsed = 0;
  const Advice a = advise(wall, o);
  EXPECT_FALSE(a.tried.empty());
  EXPECT_FALSE(a.budgetSpent);
}

// The search climbs each method's ladder (its candidates that differ in h, n and m, cheapest first)
// at rungs 0, 1, 3, 7, ... and bisects once one meets; so where every other method misses, the one
// that meets high on its ladder is found after a few probes of each, not after every cheaper
// candidate (taken in order of work, the 20 ladders that miss would be run to their 13th rung
// first: the first that meets would be the 273rd run). And nothing is lost: every candidate is
// given once.
TEST(Advice, LaddersAreClimbedAndEveryCandidateIsGiven) {
  std::vector<Method> candidates;
  std::vector<double> work;
  for (int l = 0; l <= 20; ++l)  // ladder 20 is the soft step; it meets from its 12th rung
    for (int rung = 0; rung < 16; ++rung) {
      const std::string n = "n=" + std::to_string(1 + rung);
      candidates.push_back(parseMethods(l == 20 ? "soft:" + n : "a5:" + n + ":kappa=" + std::to_string(0.25 * (1 + l)) + ":tau=0")[0]);
      work.push_back(1 + rung + 0.01 * l);
    }
  auto meets = [&](size_t c) { return c >= 20 * 16 + 12; };
  SearchOrder order(candidates, work);
  const auto never = [](double) { return false; };
  std::vector<size_t> given;
  std::optional<size_t> firstMet;
  while (const std::optional<size_t> c = order.next(never)) {
    given.push_back(*c);
    if (meets(*c) && !firstMet) firstMet = given.size();
    order.report(*c, meets(*c));
  }
  // The soft ladder's probes: rungs 0, 1, 3, 7, the top (15), then bisection: 11, 13, 12; the
  // rungs between come from the cheapest-first fill (rung 2 before the top: the top's work, 16,
  // is more than kReach = 4 times the cheapest left until every rung 0 to 3 has run).
  std::vector<size_t> soft;
  for (size_t c : given)
    if (c >= 20 * 16) soft.push_back(c - 20 * 16);
  EXPECT_EQ(std::vector<size_t>(soft.begin(), soft.begin() + 8), (std::vector<size_t>{0, 1, 3, 7, 2, 15, 11, 13}));
  ASSERT_TRUE(firstMet);
  EXPECT_LE(*firstMet, 130u);  // in order of work: the 273rd
  // Every candidate once.
  std::vector<size_t> sorted = given;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(sorted.size(), candidates.size());
  EXPECT_EQ(std::adjacent_find(sorted.begin(), sorted.end()), sorted.end());
  // What the work rules out is not given, and is what left() reports.
  SearchOrder cut(candidates, work);
  const auto cheap = [](double w) { return w > 2.5; };
  size_t n = 0;
  while (const std::optional<size_t> c = cut.next(cheap)) {
    EXPECT_LE(work[*c], 3);
    cut.report(*c, false);
    ++n;
  }
  EXPECT_EQ(n, 21u * 2);
  EXPECT_TRUE(cut.left(cheap).empty());
  EXPECT_EQ(SearchOrder(candidates, work).left(cheap).size(), 21u * 2);
}

// A ladder is the method as read, not as written: candidates whose specs give the same settings in
// another order or spelling are searched exactly as if all were written alike.
TEST(Advice, ALadderIsTheMethodNotItsSpelling) {
  const auto order = [](bool mixed) {
    std::vector<Method> candidates;
    std::vector<double> work;
    for (int l = 0; l < 3; ++l)
      for (int rung = 0; rung < 16; ++rung) {
        const std::string n = "n=" + std::to_string(1 + rung), kappa = std::to_string(0.25 * (1 + l));
        const bool other = mixed && rung % 2;
        candidates.push_back(parseMethods(other ? "a5:tau=0.0:kappa=" + kappa + ":" + n : "a5:" + n + ":kappa=" + kappa + ":tau=0")[0]);
        work.push_back(1 + rung + 0.01 * l);
      }
    SearchOrder search(candidates, work);
    std::vector<size_t> given;
    while (const std::optional<size_t> c = search.next([](double) { return false; })) {
      given.push_back(*c);
      search.report(*c, *c % 16 >= 12);  // each ladder meets from its 12th rung
    }
    return given;
  };
  EXPECT_EQ(order(true), order(false));
}

// The Bullet peer's state is ours: the same poses and velocities, angular velocity in the body
// frame.
TEST(BulletPeer, StateRoundTripAndPenetration) {
  const Scene s = sceneFrom(R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [5, 0.5, 5]}, "position": [0, -0.5, 0]},
      {"name": "box", "shape": {"type": "box", "half_extents": [0.5, 0.25, 0.5]}, "position": [0, 0.24, 0], "mass": 1,
       "orientation": [0.9238795, 0, 0.3826834, 0], "angular_velocity": [0, 2, 0], "velocity": [1, 0, 0]}]})");
  BulletPeer peer(s.model, s.initial, 1.0 / 60, 10);
  State st;
  peer.state(st);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_LT((st.bodies[i].x - s.initial.bodies[i].x).norm(), 1e-6);
    EXPECT_LT((st.bodies[i].w - s.initial.bodies[i].w).norm(), 1e-5);
    EXPECT_LT((st.bodies[i].v - s.initial.bodies[i].v).norm(), 1e-6);
  }
  peer.step();
  const BulletPeer::Penetration p = peer.penetration();
  EXPECT_GT(p.points, 0);  // it starts 1 cm into the ground
  EXPECT_GT(p.deepest, 0.001);
  EXPECT_LT(p.deepest, 0.02);
}

// The timeline's criterion markers (lab/timeline.h) are the verdict's own checks as the run goes:
// the step a bound first fails at is the length of the shortest run the verdict fails on it.
TEST(Timeline, ABoundFirstFailsWhereAShorterRunStillPasses) {
  const Scene scene = loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/atlas/mass_ratio_box_100.json");
  const Method method = parseMethods("a5").front();
  SolverOverrides o = method.overrides;
  const SolverSettings settings = resolve(o);
  World world(scene.model, settings, scene.initial);
  TimelineWatch watch(scene, 3);
  watch.add(takeSnapshot(world));
  for (int k = 0; k < 60; ++k) {
    world.step();
    watch.add(takeSnapshot(world));
  }
  std::optional<TimelineMarker> pen;
  for (const TimelineMarker& m : watch.markers())
    if (m.kind == "criterion" && m.text.find("penetration") != std::string::npos) pen = m;
  ASSERT_TRUE(pen) << "a5 fails this scene's penetration bound (tests/data/atlas_expected.json)";
  ASSERT_GT(pen->step, 1);
  EXPECT_EQ(scene.model.bodies[static_cast<size_t>(pen->body)].name, "light_box");
  auto penetrationCheck = [&](long long steps) {
    RunSetup setup;
    setup.seconds = static_cast<double>(steps) * settings.dt;
    const RunResult r = runMethod(scene, method, setup);
    EXPECT_EQ(r.stepsDone, steps);
    for (const Check& c : judge(scene, r).checks)
      if (c.text.find("penetration") != std::string::npos) return c;
    ADD_FAILURE() << "no penetration check";
    return Check{};
  };
  EXPECT_FALSE(penetrationCheck(pen->step).ok);
  EXPECT_EQ(penetrationCheck(pen->step).text, pen->text);
  EXPECT_TRUE(penetrationCheck(pen->step - 1).ok);
  // The worst penetration so far is the deepest contact of any kept step.
  const auto worst = watch.worst("penetration");
  ASSERT_TRUE(worst);
  EXPECT_GT(worst->value, 0.01);
}
