// The ODE and MuJoCo peers (lab/ode_peer.h, lab/mujoco_peer.h) against closed forms, beside
// substep's own methods and Bullet where physics says they must agree, and what they refuse.
#include "lab/chart.h"
#include "lab/chart_labels.h"
#include "lab/compare.h"
#include "lab/method.h"
#include "lab/metrics.h"
#include "lab/peers.h"
#include "lab/reference.h"
#include "lab/runner.h"
#include "run_substep.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>

using namespace substep;
using namespace substep::lab;

namespace {

const std::string kScenes = SUBSTEP_SOURCE_DIR "/assets/scenes";
constexpr double kG = 9.81;  // [m/s²], the scenes' gravity

Scene sceneFrom(const std::string& json) { return parseScene(json, "t.json", "."); }

Method method(const std::string& spec) {
  const std::vector<Method> m = parseMethods(spec);
  EXPECT_EQ(m.size(), 1u);
  return m[0];
}

RunResult runFor(const Scene& s, const std::string& spec, double seconds, double frameRate = 0) {
  std::optional<PreparedReference> ref;
  if (s.criteria && s.criteria->reference) ref = prepareReference(s, *s.criteria->reference, seconds);
  RunSetup setup;
  setup.seconds = seconds;
  setup.frameRate = frameRate;
  setup.reference = ref ? &*ref : nullptr;
  return runMethod(s, method(spec), setup);
}

}  // namespace

// A bar swinging 60 degrees about its end: the period of the closed form (1.7584 s) under every
// peer, which fails if a peer's anchor, mass or inertia is mapped wrong. Measured: ODE 1.7587 s
// (both steps), MuJoCo 1.7584 s.
TEST(Peers, PendulumPeriodMatchesTheClosedForm) {
  const Scene s = loadScene(kScenes + "/reference/physical_pendulum.json");
  for (const char* spec : {"ode", "ode:step=big", "mujoco", "mujoco:solver=pgs:integrator=rk4"}) {
    const RunResult r = runFor(s, spec, 5);
    ASSERT_FALSE(r.refused) << spec << ": " << r.stopped;
    ASSERT_TRUE(r.metrics.periodMeasured) << spec << ": " << r.metrics.referenceText;
    EXPECT_NEAR(*r.metrics.periodMeasured, *r.metrics.periodReference, 1e-3) << spec;
    EXPECT_NEAR(r.metrics.energyEnd, r.metrics.energyStart, 0.002 * r.metrics.energyStart) << spec;
  }
}

// Free fall: both peers integrate by symplectic Euler, as substep does, so after T at step h the
// height is off by exactly g h T / 2 (References.FreeFallErrorIsHalfGHT, the metric's own test).
TEST(Peers, FreeFallErrorIsHalfGHT) {
  const Scene s = loadScene(kScenes + "/reference/free_fall.json");
  const double T = 2;
  for (const char* spec : {"ode:h=1/60", "ode:h=1/120", "mujoco:h=1/60", "mujoco:h=1/120"}) {
    const RunResult r = runFor(s, spec, T);
    ASSERT_TRUE(r.metrics.trajectoryError) << spec;
    EXPECT_NEAR(*r.metrics.trajectoryError, 0.5 * kG * r.settings.dt * T, 1e-9) << spec;
  }
}

// A ball dropped 1.25 m onto the ground with restitution 0.5 lands at sqrt(2 g h) and rises to
// e² h = 0.3125 m under ODE. MuJoCo has no coefficient of restitution: it refuses the scene with
// that reason; without restitution it lands when the closed form says and stays down.
TEST(Peers, BallFallsAndBouncesAsTheClosedFormSays) {
  const std::string ball = R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [5, 0.5, 5]}, "position": [0, -0.5, 0], "restitution": @E@},
      {"name": "ball", "shape": {"type": "sphere", "radius": 0.25}, "position": [0, 1.5, 0], "mass": 1, "restitution": @E@}]})";
  auto with = [&](const char* e) {
    std::string t = ball;
    for (size_t at; (at = t.find("@E@")) != std::string::npos;) t.replace(at, 3, e);
    return sceneFrom(t);
  };
  const double h = 1.0 / 240, drop = 1.25, landing = std::sqrt(2 * drop / kG);
  const Scene bouncy = with("0.5");
  const RunResult ode = runFor(bouncy, "ode:h=1/240", 1.6, 240);
  ASSERT_FALSE(ode.refused) << ode.stopped;
  double firstLow = 1e9, apexAfter = 0;
  size_t k = 0;
  for (; k < ode.frames.size() && ode.frames[k].time < landing + 0.05; ++k) firstLow = std::min(firstLow, ode.frames[k].bodies[1].x.y());
  for (; k < ode.frames.size(); ++k) apexAfter = std::max(apexAfter, ode.frames[k].bodies[1].x.y());
  EXPECT_NEAR(firstLow, 0.25, 0.01);  // it reached the ground, not further
  EXPECT_NEAR(apexAfter - 0.25, 0.25 * drop, 0.03) << "rebound apex above the ground";
  EXPECT_NEAR(ode.metrics.speedMax, std::sqrt(2 * kG * drop), 0.05);

  const RunResult refused = runFor(bouncy, "mujoco", 1);
  EXPECT_TRUE(refused.refused);
  EXPECT_NE(refused.stopped.find("has restitution 0.5 (MuJoCo has no coefficient of restitution"), std::string::npos)
      << refused.stopped;

  const RunResult mj = runFor(with("0"), "mujoco:h=1/240", 1.6, 240);
  ASSERT_FALSE(mj.refused) << mj.stopped;
  double landed = -1, highAfter = 0;
  for (const State& f : mj.frames) {
    if (landed < 0 && f.bodies[1].x.y() <= 0.25 + 1e-3) landed = f.time;
    if (landed >= 0 && f.time > landed + 0.1) highAfter = std::max(highAfter, f.bodies[1].x.y());
  }
  EXPECT_NEAR(landed, landing, 2 * h);
  EXPECT_LT(highAfter, 0.25 + 0.005);  // no bounce
  EXPECT_GT(highAfter, 0.25 - 0.01);   // and not through the ground
}

// A box, a capsule and a cylinder lying on the ground (a static plane) stay there: a wrong turn of
// the capsule's or cylinder's axis (ODE's and MuJoCo's are Z, ours Y) stands them up and they fall
// over, a plane placed wrong or a missing contact margin (MuJoCo drops contacts at distance 0)
// lets them through the ground. (On a ground box, ODE's capsule-box test lets the capsule sink
// 10 mm and rock at 4 cm/s: measured, its own.)
TEST(Peers, BodiesAtRestOnTheGroundStayThere) {
  const Scene s = sceneFrom(R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "plane", "normal": [0, 1, 0], "offset": 0}, "friction": 0.8},
      {"name": "box", "shape": {"type": "box", "half_extents": [0.5, 0.5, 0.5]}, "position": [0, 0.5, 0], "mass": 1, "friction": 0.8},
      {"name": "capsule", "shape": {"type": "capsule", "radius": 0.2, "half_height": 0.5}, "position": [3, 0.2, 0],
       "orientation": [0.7071067811865476, 0.7071067811865476, 0, 0], "mass": 1, "friction": 0.8},
      {"name": "cylinder", "shape": {"type": "cylinder", "radius": 0.3, "half_height": 0.4}, "position": [-3, 0.3, 0],
       "orientation": [0.7071067811865476, 0.7071067811865476, 0, 0], "mass": 1, "friction": 0.8}]})");
  for (const char* spec : {"ode", "ode:step=big", "mujoco", "mujoco:cone=elliptic"}) {
    const RunResult r = runFor(s, spec, 2);
    ASSERT_FALSE(r.refused) << spec << ": " << r.stopped;
    EXPECT_LT(r.metrics.displacementMax, 0.005) << spec << ": " << r.metrics.displacementBody;
    EXPECT_LT(r.metrics.jitter, 0.01) << spec;
    EXPECT_LT(r.metrics.penetrationEnd, 0.004) << spec;
  }
}

// A triple pendulum on hinges keeps its energy (88.29 J, no contact, no friction) as far as the
// integrator allows: MuJoCo's RK4 to 0.002 % at h = 1/240, its Euler to 0.16 %, ODE to 2.0 %
// (its joint error correction takes energy out). Energy is ours, from the states read back: a
// mass, inertia or anchor mapped wrong changes the motion under our model's energy and breaks it.
TEST(Peers, ChainKeepsItsEnergy) {
  const Scene s = loadScene(kScenes + "/compare/pendulum.json");
  const std::pair<const char*, double> cases[] = {
      {"mujoco:integrator=rk4:h=1/240", 1e-4}, {"mujoco:h=1/240", 5e-3}, {"ode:h=1/240", 0.03}, {"ode:step=big:h=1/240", 0.03}};
  for (const auto& [spec, share] : cases) {
    RunSetup setup;
    setup.seconds = 2;
    const RunResult r = runMethod(s, method(spec), setup);
    ASSERT_FALSE(r.refused) << spec << ": " << r.stopped;
    EXPECT_NEAR(r.metrics.energyEnd, r.metrics.energyStart, share * r.metrics.energyStart) << spec;
    EXPECT_GT(r.metrics.speedMax, 3) << spec;  // it swung
  }
}

// Five boxes resting on each other rest under every engine: substep's methods, Bullet and both
// peers. Measured (3 s, h = 1/60): the top box moves 0.3 cm (Bullet), 1.0 (a5), 1.7 (ODE QuickStep),
// 2.7 (MuJoCo, its soft contacts settle), sideways at most 1.4 cm (ODE). ODE's big-matrix step is left out: it lets this stack
// collapse at 0.45 s (docs/lab.md).
TEST(Peers, RestingStackStaysRestingInAll) {
  const Scene s = loadScene(kScenes + "/stack.json");
  for (const char* spec : {"a2", "a5", "soft", "bullet", "ode", "ode:it=50", "mujoco", "mujoco:solver=pgs"}) {
    const RunResult r = runFor(s, spec, 3);
    ASSERT_FALSE(r.refused) << spec << ": " << r.stopped;
    EXPECT_LT(r.metrics.sidewaysMax, 0.02) << spec;
    EXPECT_LT(r.metrics.displacementMax, 0.04) << spec;
    EXPECT_FALSE(r.metrics.collapseTime) << spec;
    EXPECT_EQ(r.metrics.failure.verdict().rfind("stands", 0), 0u) << spec << ": " << r.metrics.failure.verdict();
    // Run again in this process, it steps the same states (ODE's QuickStep draws on a global
    // random generator: the peer seeds it for every run).
    EXPECT_EQ(runFor(s, spec, 3).hashes.last, r.hashes.last) << spec;
  }
}

// A body's state read back from a peer is ours: a box spinning about a principal axis with no
// gravity keeps its angular velocity and turns by ω t about it, and drifts at its velocity. A
// wrong quaternion order or angular velocity frame fails it.
TEST(Peers, StateIsReadBackInSubstepsFrames) {
  const Scene s = sceneFrom(R"({"gravity": [0, 0, 0], "bodies": [{"name": "b", "mass": 2,
      "shape": {"type": "box", "half_extents": [0.1, 0.2, 0.4]}, "position": [1, 2, 3],
      "orientation": [0.9238795325112867, 0.3826834323650898, 0, 0], "velocity": [0.5, 0, -1],
      "angular_velocity": [0, -2.1213203435596424, 2.1213203435596424]}]})");  // 3 rad/s about the body's z
  const double T = 1;
  for (const char* spec : {"ode:gyro=none", "ode", "mujoco", "mujoco:integrator=rk4"}) {
    const RunResult r = runFor(s, spec, T, 60);
    ASSERT_FALSE(r.refused) << spec << ": " << r.stopped;
    const BodyState& a = r.frames.front().bodies[0];
    const BodyState& b = r.frames.back().bodies[0];
    EXPECT_NEAR(r.frames.back().time, T, 1e-9) << spec;
    EXPECT_LT((b.x - (a.x + T * a.v)).norm(), 1e-9) << spec;
    EXPECT_LT((b.v - a.v).norm(), 1e-12) << spec;
    const Vec3 axis = Vec3(0, -1, 1).normalized();
    EXPECT_LT((b.worldAngularVelocity() - 3 * axis).norm(), 1e-9) << spec;
    EXPECT_LT((b.w - Vec3(0, 0, 3)).norm(), 1e-9) << spec;  // ours is in the body's frame
    // ODE turns a body by its first-order update, normalized: (ω h)³ / 12 a step, 0.6 mrad here.
    const Quat expected = Quat(Eigen::AngleAxisd(3 * T, axis)) * a.q;
    EXPECT_LT(expected.angularDistance(b.q), std::string(spec).rfind("ode", 0) == 0 ? 1e-3 : 1e-9) << spec;
  }
}

// What a peer cannot model is refused by `substep run` with the reason and exit status 2, and a
// peer's run writes a record that `substep rerun` steps again to the same states.
TEST(Peers, RunRefusesWhatAPeerCannotModelAndItsRecordReruns) {
  using substep_test::runSubstep;
  const auto ragdoll = runSubstep("run assets/scenes/ragdoll.json --method ode -q");
  EXPECT_EQ(ragdoll.status, 2) << ragdoll.output;
  EXPECT_NE(ragdoll.output.find("no ODE peer for this scene: joint \"ragdoll_0_spine\" is a cone_twist (ODE has no swing cone"),
            std::string::npos) << ragdoll.output;
  const auto shapes = runSubstep("run assets/scenes/shapes.json --method mujoco -q");
  EXPECT_EQ(shapes.status, 2) << shapes.output;
  EXPECT_NE(shapes.output.find("no MuJoCo peer for this scene: body \"bowl\" is a mesh"), std::string::npos) << shapes.output;
  const auto mixed = runSubstep("run assets/scenes/stack.json --method ode --kappa 1 -q");
  EXPECT_EQ(mixed.status, 2) << mixed.output;
  EXPECT_NE(mixed.output.find("--kappa is a setting of substep's algorithms; the ODE peer takes its own in --method"),
            std::string::npos) << mixed.output;

  const std::filesystem::path d = substep_test::emptyScratchFolder("peers");
  for (const char* spec : {"ode:it=20", "mujoco:solver=cg"}) {
    const std::string m = (d / (std::string(spec).substr(0, 3) + ".json")).string();
    const auto run = runSubstep("run assets/scenes/stack.json --seconds 1 --method " + std::string(spec) + " --metrics " + m);
    ASSERT_EQ(run.status, 0) << run.output;
    EXPECT_NE(run.output.find("verdict   stands"), std::string::npos) << run.output;
    const auto again = runSubstep("rerun " + m);
    EXPECT_EQ(again.status, 0) << again.output;
    EXPECT_NE(again.output.find("same"), std::string::npos) << again.output;
  }
}

// The comparison's table: the front in (real-time factor, error), the curve with most runs on it
// leading, refusals and divergences named. Rows as a sweep writes them, made up.
TEST(Compare, WhoLeadsIsTheCurveWithMostRunsOnTheFront) {
  auto row = [](const std::string& method, const std::string& family, const std::string& h, double dt, double msPerSecond,
                double error) {
    return nlohmann::json{{"scene", "s"}, {"method", method}, {"family", family}, {"h", h},
                          {"settings", {{"dt", dt}, {"iterations", 10}}}, {"cost", {{"ms_per_second", msPerSecond}}},
                          {"error", {{"metric", "trajectory_error"}}}, {"values", {{"trajectory_error", error}}},
                          {"refused", false}, {"diverged", false}, {"finite", true}};
  };
  std::vector<nlohmann::json> rows = {
      row("fast", "a5", "1/30", 1.0 / 30, 1, 0.5),   row("fast", "a5", "1/60", 1.0 / 60, 2, 0.2),
      row("fast", "a5", "1/120", 1.0 / 120, 4, 0.1), row("exact", "mujoco", "1/30", 1.0 / 30, 10, 0.01),
      row("exact", "mujoco", "1/60", 1.0 / 60, 20, 0.005), row("slow", "ode", "1/30", 1.0 / 30, 8, 0.4)};
  rows.push_back(row("gone", "bullet", "1/30", 1.0 / 30, 1, 1));
  rows.back()["diverged"] = true;
  rows.push_back(row("never", "ode", "1/60", 1.0 / 60, 1, 1));
  rows.back()["refused"] = true;
  rows.back()["stopped"] = "no ODE peer for this scene: joint \"j\" is a cone_twist";
  const std::vector<SceneComparison> c = compareRuns(rows);
  ASSERT_EQ(c.size(), 1u);
  ASSERT_EQ(c[0].front.size(), 5u);  // ode 1/30 is beaten by mujoco 1/30 on both
  EXPECT_DOUBLE_EQ(c[0].front[0].speed, 1000);  // fastest first: 1000 / (1 ms a simulated second)
  EXPECT_EQ(c[0].front.back().method, "exact");
  EXPECT_EQ(c[0].leader, "fast");  // three runs on the front against two
  EXPECT_EQ(c[0].mostAccurate.h, "1/60");
  EXPECT_EQ(c[0].diverged, std::vector<std::string>{"gone h=1/30"});
  const std::string t = comparisonTable(c);
  EXPECT_NE(t.find("| s | trajectory error | fast | fast h=1/30 (50.0 cm, 1000x); "), std::string::npos) << t;
  EXPECT_NE(t.find("- s, never: no ODE peer for this scene: joint \"j\" is a cone_twist"), std::string::npos) << t;

  // The speed chart: a curve a method, its points by h, at x = the real-time factor.
  const std::vector<Chart> charts = makeCharts(rows, ChartOptions{});
  const auto speed = std::find_if(charts.begin(), charts.end(), [](const Chart& x) { return x.name == "s-speed"; });
  ASSERT_NE(speed, charts.end());
  EXPECT_NE(speed->data.find("1000 0.5\n500 0.2\n250 0.1\n\n\n"), std::string::npos) << speed->data;
  EXPECT_NE(speed->script.find("title \"exact\""), std::string::npos) << speed->script;
  EXPECT_EQ(speed->script.find("gone"), std::string::npos);  // diverged runs are not a curve
}

// The speed chart's h labels never overlap: ten curves whose ends fall on one another get each end
// labelled where the label fits clear of every marker, line and other label, or named in the
// chart's notes; and where every curve has the same time steps, the title says which end is which.
TEST(Compare, SpeedChartLabelsNeverOverlap) {
  auto row = [](int m, const std::string& h, double dt, double msPerSecond, double error) {
    return nlohmann::json{{"scene", "s"}, {"method", "a2:m=" + std::to_string(m) + ":h=" + h}, {"family", "a2"}, {"h", h},
                          {"settings", {{"dt", dt}, {"iterations", m}}}, {"cost", {{"ms_per_second", msPerSecond}}},
                          {"error", {{"metric", "trajectory_error"}}}, {"values", {{"trajectory_error", error}}},
                          {"refused", false}, {"diverged", false}, {"finite", true}};
  };
  std::vector<nlohmann::json> rows;
  for (int k = 0; k < 10; ++k) {
    const int m = 2 + k;
    rows.push_back(row(m, "1/30", 1.0 / 30, 1 + 0.01 * k, 0.5));
    rows.push_back(row(m, "1/60", 1.0 / 60, 2 + 0.01 * k, 0.2));
    if (k == 0) rows.push_back(row(m, "1/120", 1.0 / 120, 4, 0.1));  // steps not all the same: ends labelled
  }
  const ChartOptions options;
  auto speedOf = [&](const std::vector<nlohmann::json>& r) {
    for (const Chart& c : makeCharts(r, options))
      if (c.name == "s-speed") return c;
    ADD_FAILURE() << "no speed chart";
    return Chart{};
  };
  const Chart c = speedOf(rows);
  const std::regex label(R"re(set label \d+ "([^"]*)" at screen ([0-9.e-]+), screen ([0-9.e-]+) left)re");
  std::vector<Box> boxes;
  for (auto it = std::sregex_iterator(c.script.begin(), c.script.end(), label); it != std::sregex_iterator(); ++it)
    boxes.push_back(labelBox((*it)[1], std::stod((*it)[2]) * options.width, (1 - std::stod((*it)[3])) * options.height));
  for (size_t i = 0; i < boxes.size(); ++i)
    for (size_t j = i + 1; j < boxes.size(); ++j) EXPECT_FALSE(boxes[i].overlaps(boxes[j])) << i << " " << j << "\n" << c.script;
  size_t unlabelled = 0;
  for (const std::string& n : c.notes)
    if (n.rfind("h not labelled", 0) == 0) unlabelled = static_cast<size_t>(std::count(n.begin(), n.end(), ',')) + 1;
  EXPECT_GE(boxes.size(), 2u);
  EXPECT_EQ(boxes.size() + unlabelled, 20u) << c.script;  // two ends a curve
  rows.erase(rows.begin() + 2);  // the 1/120 point: every curve over 1/30 and 1/60
  const Chart same = speedOf(rows);
  EXPECT_NE(same.title.find("h from 1/30 (right) to 1/60 (left)"), std::string::npos) << same.title;
  EXPECT_EQ(same.script.find("set label 100"), std::string::npos) << same.script;
}

// `substep compare` end to end on one scene: the sweep's records, the speed chart (a PNG) and the
// table, with what a peer refused named in it.
TEST(Compare, CommandWritesRecordsChartsAndTable) {
  const std::filesystem::path d = substep_test::emptyScratchFolder("compare");
  const auto r = substep_test::runSubstep("compare --scenes compare/grasp_stack,compare/ragdoll_pile --methods a2:m=10,ode,mujoco "
                                          "--dt 1/30,1/60 --repeat 1 --seconds 0.3 -q -o " + d.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output, "");
  EXPECT_TRUE(std::filesystem::is_regular_file(d / "compare.jsonl"));
  EXPECT_GT(std::filesystem::file_size(d / "grasp_stack-speed.png"), 10000u);
  std::ifstream in(d / "table.md");
  const std::string table((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(table.find("| grasp_stack | trajectory error | "), std::string::npos) << table;
  EXPECT_NE(table.find("- ragdoll_pile, mujoco: no MuJoCo peer for this scene: joint \"ragdoll_0_spine\" is a cone_twist"),
            std::string::npos) << table;
}
