// Contacts beyond the report's normal row: restitution, speculative points at every τ, friction
// impulses carried across a change of tangent basis, and the options that select the report's
// literal behaviour (contact blocks off, friction in the bias update).
#include "physics/scene_file.h"
#include "physics/steppers/stepper.h"
#include "physics/world.h"
#include "row_compare.h"
#include "step_inputs.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace substep;

namespace {

Scene sceneFrom(const std::string& json) { return parseScene(json, "<test>", "."); }

SolverSettings settingsFor(Algorithm a, SolverOverrides o = {}) {
  o.set(&SolverSettings::algorithm, a);
  return resolve(o);
}

class EveryAlgorithm : public ::testing::TestWithParam<Algorithm> {};
std::string algoName(const ::testing::TestParamInfo<Algorithm>& i) { return algorithmName(i.param); }

// A ball of radius 0.2 m dropped from 1 m (its bottom 1 m above the ground), restitution e on both.
Scene bouncingBall(double e) {
  return sceneFrom(R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [5, 0.5, 5]}, "position": [0, -0.5, 0],
       "restitution": )" + std::to_string(e) + R"(},
      {"name": "ball", "shape": {"type": "sphere", "radius": 0.2}, "position": [0, 1.2, 0], "restitution": )" +
                   std::to_string(e) + "}]}");
}

// Height of the ball's bottom at the top of its first rebound, over 1.5 s; -1 if it never rose.
double reboundHeight(const Scene& s, const SolverSettings& st) {
  World w(s.model, st, s.initial);
  bool rising = false;
  double apex = -1;
  for (int k = 0; k * st.dt < 1.5; ++k) {
    EXPECT_TRUE(w.step().finite);
    const BodyState& b = w.state().bodies[1];
    if (b.v.y() > 0) rising = true;
    if (rising) apex = std::max(apex, b.x.y() - 0.2);
    if (rising && b.v.y() < 0) break;
  }
  return apex;
}

}  // namespace

// Restitution (an extension: the report has none): a ball dropped from 1 m rebounds to e² of it.
// Measured at h = 1/60 (e = 0.5, e² = 0.25 m): A1 and A2 0.229 m (their one step of h loses
// g h v on the way up), A3-A5 and soft 0.243 m; at h = 1/240 all within 3 %. Below the threshold
// (1 m/s) nothing bounces, and --no-restitution turns it off.
TEST_P(EveryAlgorithm, BallReboundsToESquaredOfItsHeight) {
  const Scene s = bouncingBall(0.5);
  const double coarse = reboundHeight(s, settingsFor(GetParam()));
  SolverOverrides fine;
  fine.set(&SolverSettings::dt, 1.0 / 240);
  const double small = reboundHeight(s, settingsFor(GetParam(), fine));
  std::printf("%s: rebound %.4f m at h = 1/60, %.4f m at 1/240 (e² h = 0.25 m)\n", algorithmName(GetParam()), coarse,
              small);
  EXPECT_NEAR(coarse, 0.25, 0.1 * 0.25);
  EXPECT_NEAR(small, 0.25, 0.03 * 0.25);
  SolverOverrides off;
  off.set(&SolverSettings::restitution, false);
  EXPECT_LT(reboundHeight(s, settingsFor(GetParam(), off)), 0.002);
  SolverOverrides high;
  high.set(&SolverSettings::restitutionThreshold, 5);  // the ball lands at 4.4 m/s
  EXPECT_LT(reboundHeight(s, settingsFor(GetParam(), high)), 0.002);
}

// Speculative points close a gap at full speed, not τ of it: five boxes dropped 0.3 m apart onto
// each other come to rest touching (each gap within the slop, 1 mm), at τ = 0 as at Havok's 0.6.
// Before, at τ = 0 they stopped 3 to 9 mm above each other (docs/algorithms.md).
TEST_P(EveryAlgorithm, BoxesDroppedOntoEachOtherRestTouching) {
  const Scene s = sceneFrom(R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [5, 0.5, 5]}, "position": [0, -0.5, 0]}],
    "generators": [{"type": "stack", "count": 5, "half_extents": [0.5, 0.25, 0.5], "gap": 0.3, "position": [0, 0.3, 0]}]})");
  std::vector<SolverOverrides> variants(1);
  if (havokScaled(GetParam())) {
    // τ = 0 has no position feedback at all: the impacts' compressions that one sweep per
    // sub-step leaves are never corrected, and cold the stack sinks (the bottom box 8 cm into the
    // ground after 3 s); warm started, as pyramid.json runs it, it holds.
    variants.assign(3, SolverOverrides{});
    variants[0].set(&SolverSettings::tau, 0);
    variants[0].set(&SolverSettings::kappa, 0.85);
    variants[0].set(&SolverSettings::warmStart, true);
    variants[1].set(&SolverSettings::tau, 0.3);
    variants[2].set(&SolverSettings::tau, 0.6);
    for (auto& v : variants) v.set(&SolverSettings::contactBlocks, true);  // without them one sweep rocks the boxes (below)
  }  for (const SolverOverrides& o : variants) {
    World w(s.model, settingsFor(GetParam(), o), s.initial);
    for (int k = 0; k < 180; ++k) ASSERT_TRUE(w.step().finite);
    double worstGap = 0, worstDepth = 0;
    for (int i = 1; i <= 5; ++i) {
      const double below = i == 1 ? 0.0 : w.state().bodies[static_cast<size_t>(i - 1)].x.y() + 0.25;
      const double gap = w.state().bodies[static_cast<size_t>(i)].x.y() - 0.25 - below;
      worstGap = std::max(worstGap, gap);
      worstDepth = std::max(worstDepth, -gap);
    }
    std::printf("%s tau %s: largest gap %.2f mm, deepest %.2f mm\n", algorithmName(GetParam()),
                o.get(&SolverSettings::tau) ? std::to_string(*o.get(&SolverSettings::tau)).c_str() : "-", worstGap * 1e3, worstDepth * 1e3);
    EXPECT_LT(worstGap, 0.0005);  // touching: no box held above the next by its speculative point
    // ... and within about the slop; soft contacts are springs that the weight above compresses.
    EXPECT_LT(worstDepth, GetParam() == Algorithm::Soft ? 0.005 : 0.004);
  }
}

// Landing fast on speculative points: a box at 6.6 m/s neither sinks in nor bounces.
TEST_P(EveryAlgorithm, FastImpactNeitherSinksNorBounces) {
  const Scene s = sceneFrom(R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [5, 0.5, 5]}, "position": [0, -0.5, 0]},
      {"name": "box", "shape": {"type": "box", "half_extents": [0.3, 0.2, 0.25]}, "position": [0, 2.4, 0]}]})");
  SolverOverrides o;
  if (havokScaled(GetParam())) o.set(&SolverSettings::contactBlocks, true);
  World w(s.model, settingsFor(GetParam(), o), s.initial);
  double lowest = 1e9, highestAfter = -1e9, maxPen = 0;
  bool landed = false;
  for (int k = 0; k < 120; ++k) {
    w.step();
    const double y = w.state().bodies[1].x.y();
    maxPen = std::max(maxPen, w.maxPenetration());
    if (y < 0.25 && std::abs(w.state().bodies[1].v.y()) < 1) landed = true;  // stopped near the ground
    if (landed) highestAfter = std::max(highestAfter, y);
    lowest = std::min(lowest, y);
  }
  ASSERT_TRUE(landed);
  EXPECT_GT(lowest, 0.2 - 0.005);       // never more than 5 mm in
  EXPECT_LT(highestAfter, 0.2 + 0.005);  // and no bounce
  EXPECT_LT(maxPen, 0.005);
}

INSTANTIATE_TEST_SUITE_P(Algorithms, EveryAlgorithm,
                         ::testing::Values(Algorithm::A1, Algorithm::A2, Algorithm::A3, Algorithm::A4, Algorithm::A5,
                                           Algorithm::Soft),
                         algoName);

// The report's A3-A5 solve a manifold's normal rows one by one (IV.2.2: only unbounded rows are
// block-solved); contact blocks are an extension. Row by row, one sweep over a box's four
// coplanar points overshoots in rotation: the box landing at 6.6 m/s rises 8.4 mm after it
// stopped (the test above asks for 5 mm with blocks on).
TEST(ContactBlocks, OffInTheReportsPresetsAndWhatTheyChange) {
  const Scene s = sceneFrom(R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [5, 0.5, 5]}, "position": [0, -0.5, 0]},
      {"name": "box", "shape": {"type": "box", "half_extents": [0.3, 0.2, 0.25]}, "position": [0, 2.4, 0]}]})");
  for (const bool blocks : {false, true}) {
    SolverOverrides o;
    o.setPreset("4-medium");
    if (blocks) o.set(&SolverSettings::contactBlocks, true);
    const SolverSettings st = settingsFor(Algorithm::A5, o);
    EXPECT_EQ(st.contactBlocks, blocks);
    EXPECT_TRUE(st.blockSolve);  // the report's stable (joint) blocks stay on
    World w(s.model, st, s.initial);
    double highestAfter = -1e9;
    bool landed = false;
    int contactUnits = 0;
    for (int k = 0; k < 120; ++k) {
      w.step();
      for (const SolveUnit& u : w.constraints().units) contactUnits += u.kind == SolveUnit::Contact;
      const double y = w.state().bodies[1].x.y();
      if (y < 0.25 && std::abs(w.state().bodies[1].v.y()) < 1) landed = true;
      if (landed) highestAfter = std::max(highestAfter, y);
    }
    std::printf("contact blocks %s: highest after landing %.2f mm above rest\n", blocks ? "on" : "off",
                (highestAfter - 0.2) * 1e3);
    if (blocks) {
      EXPECT_GT(contactUnits, 0);
      EXPECT_LT(highestAfter, 0.2 + 0.005);
    } else {
      EXPECT_EQ(contactUnits, 0);
      EXPECT_GT(highestAfter, 0.2 + 0.005);  // the report's row-by-row sweep rocks it
      EXPECT_LT(highestAfter, 0.2 + 0.02);
    }
  }
}

// Friction impulses are warm-started as a vector fixed in B and projected on the new tangents,
// so a normal that crosses the point where the tangent basis switches (|n.x| = 1/√3) carries its
// friction over. Before, the old λ1, λ2 were applied along the new, unrelated tangents.
TEST(FrictionWarmStart, ImpulseCarriesAcrossTheTangentBasisSwitch) {
  Model model;
  Body ground, box;
  ground.isStatic = true;
  ground.shape.type = ShapeType::Box;
  ground.shape.halfExtents = Vec3(5, 0.5, 5);
  box.shape = ground.shape;
  box.shape.halfExtents = Vec3::Constant(0.5);
  box.mass = 1;
  box.invMass = 1;
  box.inertia = Vec3::Constant(1.0 / 6);
  box.invInertia = Vec3::Constant(6);
  model.bodies = {ground, box};
  std::vector<BodyMass> mass = {BodyMass{}, BodyMass{1, Vec3::Constant(6)}};
  SolverSettings st = resolve(SolverOverrides{});
  st.warmStart = true;
  // The normal (B's local +Y, B the ground) just below the switch, then the ground turned so the
  // world normal is just above it.
  auto manifoldAt = [&](const Vec3& n) {
    Manifold m;
    m.a = 1;
    m.b = 0;
    m.friction = 0.8;
    m.count = 1;
    m.points[0].localA = -0.5 * n;
    m.points[0].localB = Vec3::Zero();
    m.points[0].localN = Vec3::UnitY();
    m.points[0].lambda = 2;
    return m;
  };
  auto groundTurnedTo = [](const Vec3& n) {  // a pose of the ground whose +Y is n
    return Pose{Vec3::Zero(), Quat::FromTwoVectors(Vec3::UnitY(), n)};
  };
  const Vec3 n1 = Vec3(0.57, std::sqrt(1 - 0.57 * 0.57), 0), n2 = Vec3(0.585, std::sqrt(1 - 0.585 * 0.585), 0);
  std::vector<Manifold> ms = {manifoldAt(n1)};
  std::vector<Pose> poses = {groundTurnedTo(n1), Pose{n1, Quat::Identity()}};
  ConstraintSet cs;
  cs.build(model, ms, poses, mass, st, 1.0 / 60, 1.0);
  const int f = cs.frictions[0].row;
  cs.rows[static_cast<size_t>(f)].lambda = 0.3;
  cs.rows[static_cast<size_t>(f + 1)].lambda = -0.2;
  const Vec3 before = 0.3 * cs.rows[static_cast<size_t>(f)].lin - 0.2 * cs.rows[static_cast<size_t>(f + 1)].lin;
  cs.storeImpulses(ms);
  // The ground turns by 0.9 degrees: its normal crosses |n.x| = 0.57735 and the tangents switch.
  poses = {groundTurnedTo(n2), Pose{n2, Quat::Identity()}};
  cs.build(model, ms, poses, mass, st, 1.0 / 60, 1.0);
  const Row* fr = &cs.rows[static_cast<size_t>(cs.frictions[0].row)];
  const Vec3 after = fr[0].lambda * fr[0].lin + fr[1].lambda * fr[1].lin;
  const Quat turn = Quat::FromTwoVectors(n1, n2);
  std::printf("friction impulse carried: |before| %.4f, |after| %.4f, difference from the turned impulse %.2e; "
              "old tangent t1 · new t1 = %.3f\n",
              before.norm(), after.norm(), (after - turn * before).norm(), fr[0].lin.dot(turn * before.normalized()));
  EXPECT_LT((after - turn * before).norm(), 1e-9);  // the same impulse, turned with the ground
}

// The same within a step: A3 re-formulates every row between sub-steps (proc3:15), friction's
// tangents from the normal of the turned coordinates, and with warm starting each sub-step starts
// from the last one's λ. A platform (body B of the contact) turning at 0.24 rad/s carries a box's
// normal across |n.x| = 0.57735 during the first of two sub-steps, so the tangents switch. With no
// sweeps (m = 0) the impulses each sub-step applies are its warm start alone, read from the box's
// velocity change: the tangential impulse sub-step 1 applies must be sub-step 0's, kept on the
// platform as build() keeps a step's (its world direction turned by the platform's 0.11 degrees).
// Re-applied as coefficients on the new tangents it pointed 60 degrees off.
TEST(FrictionWarmStart, A3SubStepsCarryTheImpulseAcrossTheTangentBasisSwitch) {
  Model model;
  model.gravity = Vec3::Zero();
  Body box;
  box.shape.type = ShapeType::Box;
  box.shape.halfExtents = Vec3::Constant(0.5);
  box.mass = 1;
  box.invMass = 1;
  box.inertia = Vec3::Constant(1.0 / 6);
  box.invInertia = Vec3::Constant(6);
  Body platform = box;  // 100 times heavier: the impulses hardly change its turn
  platform.mass = 100;
  platform.invMass = 0.01;
  platform.inertia = Vec3::Constant(100.0 / 6);
  platform.invInertia = Vec3::Constant(0.06);
  model.bodies = {platform, box};
  std::vector<BodyMass> mass = {BodyMass{0.01, Vec3::Constant(0.06)}, BodyMass{1, Vec3::Constant(6)}};
  SolverOverrides o;
  o.set(&SolverSettings::algorithm, Algorithm::A3);
  o.set(&SolverSettings::warmStart, true);
  o.set(&SolverSettings::substeps, 2);
  o.set(&SolverSettings::restitution, false);
  SolverSettings st = resolve(o);
  st.iterations = 0;  // below the table's range: the warm starts alone

  const double yz = std::sqrt((1 - 0.5765 * 0.5765) / 2);
  const Vec3 n0(0.5765, yz, yz);  // just below the switch
  const Quat q0 = Quat::FromTwoVectors(Vec3::UnitY(), n0);
  std::vector<Pose> poses = {Pose{Vec3::Zero(), q0}, Pose{n0, q0}};
  Manifold m;
  m.a = 1;
  m.b = 0;
  m.friction = 0.8;
  m.count = 1;
  m.points[0].localA = Vec3(0, -0.5, 0);
  m.points[0].localB = Vec3(0, 0.5, 0);
  m.points[0].localN = Vec3::UnitY();
  m.points[0].lambda = 2;
  m.frictionImpulse = Vec3(0.3, 0, -0.2);  // last step's, in the platform's frame
  std::vector<Manifold> ms = {m};

  State state;
  state.bodies.resize(2);
  StepContext c;
  c.model = &model;
  c.settings = &st;
  c.state = &state;
  ConstraintSet cs;
  c.constraints = &cs;
  c.mass = mass;
  c.poses = poses;
  // The platform turns its +Y towards +x (ω = |ω| n × x̂, so ṅ·x̂ = |ω|(1 - n_x²)): 0.002 rad
  // in the sub-step of 1/120 s.
  c.v = {Vec3::Zero(), Vec3::Zero()};
  c.w = {q0.conjugate() * Vec3(0.24 * n0.cross(Vec3::UnitX()).normalized()), Vec3::Zero()};
  c.subV.assign(2 * static_cast<size_t>(st.substeps), Vec3::Zero());
  c.subW.assign(2 * static_cast<size_t>(st.substeps), Vec3::Zero());
  cs.build(model, ms, poses, mass, st, st.dt / st.substeps, 1.0);
  const Vec3 normal0 = cs.rows[static_cast<size_t>(cs.contacts[0].row)].lin;
  const Vec3 t0 = cs.rows[static_cast<size_t>(cs.frictions[0].row)].lin;
  const Vec3 box0 = c.v[1];
  makeStepper(Algorithm::A3)->stepVelocities(c);
  const Vec3 normal1 = cs.rows[static_cast<size_t>(cs.contacts[0].row)].lin;
  const Vec3 t1 = cs.rows[static_cast<size_t>(cs.frictions[0].row)].lin;
  ASSERT_LT(std::abs(normal0.x()), 0.57735);
  ASSERT_GT(std::abs(normal1.x()), 0.57735);  // the normal crossed: the tangents were rebuilt another way

  // The box's impulse in each sub-step (its mass is 1), without its part along that sub-step's normal.
  auto tangential = [](const Vec3& impulse, const Vec3& n) { return Vec3(impulse - impulse.dot(n) * n); };
  const Vec3 carried = tangential(c.subV[1] - box0, normal0);  // sub-step 0's
  const Vec3 applied = tangential(c.subV[2 + 1] - c.subV[1], normal1);  // sub-step 1's
  const Quat turn = c.subPoses[0].q * q0.conjugate();                      // the platform's, in sub-step 0
  auto degrees = [](const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)) * 180 / M_PI; };
  std::printf("a3, warm: tangent t1 switched by %.1f degrees; friction impulse of sub-step 1 %.2f degrees from "
              "sub-step 0's (%.4f against %.4f N s), %.2e N s from it turned with the platform (%.3f degrees)\n",
              degrees(t0, t1), degrees(carried, applied), applied.norm(), carried.norm(),
              (applied - turn * carried).norm(), degrees(normal0, normal1));
  EXPECT_GT(degrees(t0, t1), 10.0);
  EXPECT_LT((applied - turn * carried).norm(), 1e-12);
  EXPECT_LT(degrees(carried, applied), degrees(normal0, normal1) + 1e-9);
}

// Friction rows are velocity-level rows: under A4 they keep β = 0 (an extension, on by default);
// with --no-friction-exempt they take the bias update rule like every row, as the report's
// listing has it (proc4:16): after a step of sliding their β holds -Σ J̌v̌ʲ, the slide so far. While
// a contact slides its friction is at the bound either way and the choice changes little: a
// 1000 kg box at 4 m/s on μ 0.3 slides v²/2μg within 0.3 %, and the two differ by 0.06 mm.
TEST(FrictionExempt, FrictionTakesTheBiasUpdateOnlyWhenAsked) {
  const Scene s = sceneFrom(R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [50, 0.5, 5]}, "position": [0, -0.5, 0],
       "friction": 0.3},
      {"name": "box", "shape": {"type": "box", "half_extents": [0.5, 0.5, 0.5]}, "position": [0, 0.499, 0],
       "velocity": [4, 0, 0], "friction": 0.3}]})");
  const double closedForm = 16 / (2 * 0.3 * 9.81);  // 2.72 m
  double slid[2];
  for (const bool exempt : {true, false}) {
    SolverOverrides o;
    o.set(&SolverSettings::frictionExempt, exempt);
    o.set(&SolverSettings::contactBlocks, true);
    World w(s.model, settingsFor(Algorithm::A4, o), s.initial);
    w.step();
    double largestBias = 0;
    for (const Row& r : w.constraints().rows)
      if (r.normalRow >= 0) {
        EXPECT_EQ(r.velocityLevel, exempt);
        largestBias = std::max(largestBias, std::abs(r.bias));
      }
    if (exempt) {
      EXPECT_EQ(largestBias, 0.0);
    } else {
      EXPECT_GT(largestBias, 0.05);  // about 3 of the 4 sub-steps' slide, 4 m/s each
    }
    for (int k = 1; k < 120; ++k) w.step();  // it stops at 1.36 s
    slid[exempt] = w.state().bodies[1].x.x();
  }
  std::printf("a4: slid %.4f m with friction exempt, %.4f m with the update rule on friction (v²/2μg = %.4f m)\n",
              slid[1], slid[0], closedForm);
  EXPECT_NEAR(slid[1], closedForm, 0.02 * closedForm);
  EXPECT_NEAR(slid[0], slid[1], 1e-3);  // measured 0.06 mm apart, from the steps where it stops
}

// Every field of a row set to a value no reset gives it, nor a formulation in these tests (no body
// 1000 or 1001, no Jacobian (1, 2, 3)).
static void poison(Row& r) {
  r.a = 1000, r.b = 1001;
  r.lin = r.angA = r.angB = r.mAngA = r.mAngB = Vec3(1, 2, 3);
  r.mA = r.mB = r.effMass = r.bias = r.lo = r.hi = r.split = r.lambda = 5;
  r.normalRow = 2, r.normalCount = 4;
  r.velocityLevel = r.velocityTarget = r.speculative = r.pushed = true;
}


// A reset row is a default row, field for field (ConstraintSet::build reuses last step's rows).
TEST(Rows, ResetRowIsADefaultRow) {
  Row r;
  poison(r);
  resetRow(r);
  expectSameRow(r, Row{}, "resetRow");
}

// ConstraintSet::build formulates a manifold's rows over last step's, resetting only the fields
// formulation does not write (resetRowState): the rows it makes over rows holding anything are
// those of a new set, field for field. A stack of boxes settling (points touching and apart),
// under the soft step and under A5 without speculative points (rows apart held at zero).
TEST(Rows, ContactRowsFormulatedOverOldOnesAreNewOnes) {
  const Scene s = sceneFrom(R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [5, 0.5, 5]}, "position": [0, -0.5, 0]}],
    "generators": [{"type": "stack", "count": 4, "half_extents": [0.5, 0.25, 0.5], "gap": 0.02, "position": [0, 0.3, 0]}]})");
  SolverOverrides a5;
  a5.set(&SolverSettings::speculative, false);
  for (const SolverSettings& st : {settingsFor(Algorithm::Soft), settingsFor(Algorithm::A5, a5)}) {
    World w(s.model, st, s.initial);
    for (int k = 0; k < 20; ++k) ASSERT_TRUE(w.step().finite);
    const auto [poses, mass] = stepInputs(w);
    ConstraintSet reused, fresh;
    reused.build(s.model, w.manifolds(), poses, mass, st, st.dt, 1.0);
    ASSERT_GE(reused.contacts.size(), 8u) << algorithmName(st.algorithm);
    for (Row& r : reused.rows) poison(r);
    reused.build(s.model, w.manifolds(), poses, mass, st, st.dt, 1.0);
    fresh.build(s.model, w.manifolds(), poses, mass, st, st.dt, 1.0);
    ASSERT_EQ(reused.rows.size(), fresh.rows.size());
    for (size_t k = 0; k < fresh.rows.size(); ++k)
      expectSameRow(reused.rows[k], fresh.rows[k], std::string(algorithmName(st.algorithm)) + ", row " + std::to_string(k));
  }
}

// The soft step's colours are kept from the last step while the manifolds join the same bodies,
// each moving or not as before (ConstraintSet::colourManifolds): the 20-level pyramid settled,
// then one manifold dropped, then one body still (zero mass, as asleep). A set that colours each
// list after another has the colours a new set finds for it; and the settled list's again once
// it comes back.
TEST(Colours, KeptOnlyWhileTheManifoldsAndTheirMovingBodiesAreTheSame) {
  const Scene s = loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/pyramid.json");
  SolverOverrides o;
  o.set(&SolverSettings::colours, true);
  const SolverSettings st = settingsFor(Algorithm::Soft, o);
  World w(s.model, st, s.initial);
  for (int k = 0; k < 30; ++k) ASSERT_TRUE(w.step().finite);
  const StepInputs in = stepInputs(w);
  const std::vector<BodyMass>& mass = in.mass;
  const std::vector<Manifold> settled = w.manifolds();
  std::vector<Manifold> dropped = settled;
  dropped.erase(dropped.begin() + static_cast<long>(dropped.size() / 2));
  std::vector<BodyMass> still = mass;
  const int body = settled[settled.size() / 2].a;  // a body in the middle of the pyramid
  ASSERT_GT(still[static_cast<size_t>(body)].invMass, 0);
  still[static_cast<size_t>(body)] = BodyMass{};
  ConstraintSet kept;
  const auto expectColours = [&](const std::vector<Manifold>& ms, const std::vector<BodyMass>& m,
                                  const char* what) -> std::vector<int> {
    kept.build(s.model, ms, in.poses, m, st, st.dt, 1.0);
    ConstraintSet fresh;
    fresh.build(s.model, ms, in.poses, m, st, st.dt, 1.0);
    EXPECT_FALSE(fresh.colourStart.empty()) << what;
    EXPECT_EQ(kept.colourStart, fresh.colourStart) << what;
    EXPECT_EQ(kept.colourOrder, fresh.colourOrder) << what;
    return fresh.colourOrder;
  };
  const std::vector<int> first = expectColours(settled, mass, "settled");
  expectColours(settled, mass, "settled again");
  EXPECT_NE(expectColours(dropped, mass, "a manifold dropped"), first);
  const std::vector<int> before = kept.colourOrder;
  EXPECT_NE(expectColours(dropped, still, "a body still"), before);
  expectColours(settled, mass, "settled once more");
}

// The sweep solves a manifold's friction rows through their couplings (J̌v̌ of the later rows moved
// by the earlier rows' Δλ): the same Gauss-Seidel as row after row on the velocities, to
// round-off. Two boxes stacked on the ground, nudged (friction holds them: its rows are off their
// bounds, where the couplings matter), contact blocks off so that every other unit is a single
// row; the reference solves every unit's rows one by one with solveRow.
TEST(Rows, FrictionCouplingsAreRowByRowGaussSeidel) {
  const Scene s = sceneFrom(R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [5, 0.5, 5]}, "position": [0, -0.5, 0]},
      {"name": "a", "shape": {"type": "box", "half_extents": [0.5, 0.3, 0.4]}, "position": [0, 0.3, 0],
       "friction": 2},
      {"name": "b", "shape": {"type": "box", "half_extents": [0.3, 0.3, 0.3]}, "position": [0.1, 0.9, 0.1],
       "friction": 2}]})");
  SolverOverrides o;
  o.set(&SolverSettings::contactBlocks, false);
  World w(s.model, settingsFor(Algorithm::A2, o), s.initial);
  for (int k = 0; k < 5; ++k) w.step();
  ConstraintSet fast = w.constraints(), slow = w.constraints(), uncoupled = w.constraints();
  ASSERT_GT(fast.couplings.size(), 1u);
  for (FrictionCoupling& g : uncoupled.couplings) g = FrictionCoupling{};  // the test must see a missing coupling
  std::vector<Vec3> v1, w1;
  for (const BodyState& b : w.state().bodies) {
    v1.push_back(b.v + Vec3(0.03, -0.02, 0.01));
    w1.push_back(b.q.conjugate() * b.w + Vec3(-0.04, 0.05, 0.02));
  }
  std::vector<Vec3> v2 = v1, w2 = w1, v3 = v1, w3 = w1;
  const SweepScales k = SweepScales::psor(1.0);
  for (int it = 0; it < 3; ++it) {
    sweep(fast, v1, w1, k);
    sweep(uncoupled, v3, w3, k);
    for (const SolveUnit& u : slow.units)
      for (int i = 0; i < u.size; ++i) {
        Row& r = slow.rows[static_cast<size_t>(u.first + i)];
        const double target = (r.speculative && r.bias < 0 ? k.biasSpeculative : k.bias) * r.bias;
        solveRow(r, slow.rows.data(), v2.data(), w2.data(), [&](double jv) { return r.effMass * (target - k.vel * jv); });
      }
  }
  double worst = 0, scale = 0, wrong = 0;
  for (size_t i = 0; i < v1.size(); ++i) wrong = std::max(wrong, (v3[i] - v2[i]).norm());
  for (size_t i = 0; i < fast.rows.size(); ++i) {
    worst = std::max(worst, std::abs(fast.rows[i].lambda - slow.rows[i].lambda));
    scale = std::max(scale, std::abs(slow.rows[i].lambda));
  }
  for (size_t i = 0; i < v1.size(); ++i) worst = std::max({worst, (v1[i] - v2[i]).norm(), (w1[i] - w2[i]).norm()});
  std::printf("friction couplings against row by row: largest difference %.2e (impulses up to %.2f N s); "
              "without the couplings %.2e m/s\n", worst, scale, wrong);
  EXPECT_GT(wrong, 1e-6);
  EXPECT_GT(scale, 0.01);
  EXPECT_LT(worst, 1e-12 * (1 + scale));
}
