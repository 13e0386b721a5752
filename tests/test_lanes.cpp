// The soft step's lanes (physics/steppers/soft_lanes.h): eight manifolds solved at once give the
// numbers of one at a time, to the last bit, in the step's order (its runs) and by colours, warm
// and cold, with joints re-formulated between sub-steps; and the AVX-512, AVX2 and baseline
// kernels give the same numbers.
#include "physics/run.h"
#include "physics/scene_file.h"
#include "physics/state_hash.h"
#include "physics/steppers/soft_lanes.h"
#include "physics/steppers/soft_lanes_fill.h"
#include "physics/world.h"
#include "random_settings.h"
#include "row_compare.h"
#include "step_inputs.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <utility>
#include <vector>

using namespace substep;

namespace {

struct Stepped {
  std::vector<std::string> hashes;  // the state's after every step
  int laneRuns = 0;                 // the most runs a step solved in lanes
  int deferred = 0;                 // steps whose contact rows the lanes formulated (no row stored)
};

Stepped trajectory(const Scene& s, SolverSettings st, int steps) {
  Stepped out;
  World w(s.model, st, s.initial);
  for (int k = 0; k < steps; ++k) {
    const StepReport& r = w.step();
    out.hashes.push_back(hashText(stateHash(w.state())));
    out.laneRuns = std::max(out.laneRuns, r.solver.laneRuns);
    out.deferred += w.constraints().contactRowsDeferred();
    if (!r.finite) break;
  }
  return out;
}

// The kernels this processor runs: the baseline's, and AVX2's and AVX-512's where it has them.
std::vector<const lanes::Kernel*> availableKernels() {
  std::vector<const lanes::Kernel*> kernels = {&lanes::sse2Kernel()};
  if (lanes::avx2Supported()) kernels.push_back(&lanes::avx2Kernel());
  if (lanes::avx512Supported()) kernels.push_back(&lanes::avx512Kernel());
  return kernels;
}

SolverSettings soft(const Scene& s, bool lanes, bool colours, bool warm) {
  SolverOverrides o = s.solver;
  o.set(&SolverSettings::algorithm, Algorithm::Soft);
  o.set(&SolverSettings::lanes, lanes);
  o.set(&SolverSettings::colours, colours);
  o.set(&SolverSettings::warmStart, warm);
  return resolve(o);
}

// Whether a world's rows hold its contacts' (false: only the joints'), at its first step with contacts.
bool storesContactRows(const Scene& s, const SolverSettings& st) {
  World w(s.model, st, s.initial);
  for (int k = 0; k < 240 && w.constraints().frictions.empty(); ++k) w.step();
  const ConstraintSet& cs = w.constraints();
  EXPECT_FALSE(cs.frictions.empty());
  return cs.rows.size() == static_cast<size_t>(cs.rowCount()) && cs.rowCount() > cs.contactFirstRow;
}

Scene scene(const char* name) { return loadScene(std::string(SUBSTEP_SOURCE_DIR "/assets/scenes/") + name); }

}  // namespace

TEST(Lanes, SameTrajectoryAsOneManifoldAtATime) {
  struct Case {
    const char* scene;
    int steps;
  };
  // The pyramid: one island, levels diagonal across it; warm, the lanes formulate its contacts'
  // rows and no row is stored (ConstraintSet::askDeferredContactRows). The ragdoll pile: joints'
  // rows before the contacts and re-formulated every sub-step (the lanes' λ go back to the rows
  // each sub-step), so the contact rows are stored, as they are cold.
  for (const Case& c : {Case{"pyramid.json", 30}, Case{"ragdoll_pile.json", 30}}) {
    const Scene s = scene(c.scene);
    for (bool colours : {false, true})
      for (bool warm : {true, false}) {
        const std::string what = std::string(c.scene) + (colours ? " colours" : " levels") + (warm ? " warm" : " cold");
        const Stepped one = trajectory(s, soft(s, false, colours, warm), c.steps);
        const Stepped eight = trajectory(s, soft(s, true, colours, warm), c.steps);
        EXPECT_EQ(one.laneRuns, 0) << what;
        EXPECT_GT(eight.laneRuns, 0) << what << ": the lanes were not used";
        EXPECT_EQ(one.deferred, 0) << what;
        const bool defers = warm && std::string(c.scene) == "pyramid.json";
        EXPECT_EQ(eight.deferred, defers ? c.steps : 0) << what;
        EXPECT_EQ(storesContactRows(s, soft(s, true, colours, warm)), !defers) << what;
        ASSERT_EQ(one.hashes.size(), eight.hashes.size()) << what;
        for (size_t k = 0; k < one.hashes.size(); ++k)
          ASSERT_EQ(one.hashes[k], eight.hashes[k]) << what << ", step " << k + 1;
      }
  }
}

// With the contact rows deferred no ContactDef is stored (the lanes read the manifolds' points),
// yet the contact points a run reports (penetration, the lab's depths) are the stored rows' to the
// last bit: the soft step and A5 with pyramid.json's settings (its lane groups), lanes on and off
// (which step alike: the tests above).
TEST(Lanes, DeferredRowsReportTheSameContactPoints) {
  const Scene s = scene("pyramid.json");
  const auto settings = [&](Algorithm algorithm, bool lanes) {
    SolverOverrides o = s.solver;  // a5, κ 0.85, warm, contact blocks
    if (algorithm == Algorithm::Soft) o.set(&SolverSettings::algorithm, Algorithm::Soft);
    o.set(&SolverSettings::lanes, lanes);
    return resolve(o);
  };
  struct Point {
    int a, b;
    Vec3 localA, localB, localN, worldN, armA, armB;
    double restitution, lastLambda;
    bool worldFrame;
  };
  const auto points = [](const World& w) {
    std::vector<Point> out;
    w.constraints().eachContact([&](const ContactDef& c) {
      out.push_back({c.a, c.b, c.localA, c.localB, c.localN, c.worldN, c.armA, c.armB, c.restitution, c.lastLambda,
                     c.worldFrame});
    });
    return out;
  };
  for (const Algorithm algorithm : {Algorithm::Soft, Algorithm::A5}) {
    const std::string what = algorithmName(algorithm);
    World stored(s.model, settings(algorithm, false), s.initial), deferred(s.model, settings(algorithm, true), s.initial);
    for (int k = 0; k < 40; ++k) {
      ASSERT_TRUE(stored.step().finite) << what;
      ASSERT_TRUE(deferred.step().finite) << what;
    }
    ASSERT_FALSE(stored.constraints().contactRowsDeferred()) << what;
    ASSERT_TRUE(deferred.constraints().contactRowsDeferred()) << what;
    EXPECT_TRUE(deferred.constraints().contacts.empty()) << what << ": deferred rows still stored their points";
    const std::vector<Point> want = points(stored), got = points(deferred);
    ASSERT_GT(want.size(), 1000u) << what;  // 210 boxes resting on one another
    ASSERT_EQ(got.size(), want.size()) << what;
    for (size_t k = 0; k < want.size(); ++k) {
      const Point &p = got[k], &q = want[k];
      // Deferred, the point's last λ is not known (storeImpulses wrote the step's over it).
      ASSERT_TRUE(std::isnan(p.lastLambda) && std::isfinite(q.lastLambda)) << what << ", point " << k;
      ASSERT_TRUE(p.a == q.a && p.b == q.b && p.localA == q.localA && p.localB == q.localB && p.localN == q.localN &&
                  p.worldN == q.worldN && p.armA == q.armA && p.armB == q.armB && p.restitution == q.restitution &&
                  p.worldFrame == q.worldFrame)
          << what << ", point " << k;
    }
    ASSERT_GT(stored.maxPenetration(), 0) << what;
    EXPECT_EQ(deferred.maxPenetration(), stored.maxPenetration()) << what;
    const ContactDepths d = contactDepths(deferred), e = contactDepths(stored);
    EXPECT_GT(e.points, 0) << what;
    EXPECT_EQ(d.points, e.points) << what;
    EXPECT_EQ(d.deepest, e.deepest) << what;
    EXPECT_EQ(d.sumSquares, e.sumSquares) << what;
  }
}

// A step whose manifolds are last step's (the same bodies in the same order) keeps last step's
// runs; any other makes its own. Spheres thrown at one another between walls keep making and
// breaking contacts, often as many as the step before but between other bodies: the lanes give
// the numbers of one manifold at a time on every step, warm and cold.
TEST(Lanes, RunsAreKeptOnlyForTheSameManifolds) {
  std::string json = R"({"bodies": [{"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [4, 0.5, 4]},
      "position": [0, -0.5, 0]})";
  for (int wall = 0; wall < 4; ++wall) {
    const double x = wall == 0 ? -4.5 : wall == 1 ? 4.5 : 0, z = wall == 2 ? -4.5 : wall == 3 ? 4.5 : 0;
    const bool alongZ = wall < 2;
    json += R"(, {"name": "wall)" + std::to_string(wall) + R"(", "static": true, "shape": {"type": "box", "half_extents": [)" +
            (alongZ ? "0.5, 3, 5" : "5, 3, 0.5") + R"(]}, "position": [)" + std::to_string(x) + ", 3, " + std::to_string(z) + "]}";
  }
  int n = 0;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      for (int k = 0; k < 3; ++k, ++n) {
        const double vx = ((n * 7) % 5 - 2) * 1.5, vz = ((n * 3) % 5 - 2) * 1.5;
        json += R"(, {"name": "s)" + std::to_string(n) + R"(", "shape": {"type": "sphere", "radius": 0.4}, "position": [)" +
                std::to_string(-3 + 1.2 * i) + ", " + std::to_string(0.5 + 1.0 * k) + ", " + std::to_string(-3 + 1.2 * j) +
                R"(], "velocity": [)" + std::to_string(vx) + ", 0, " + std::to_string(vz) + "]}";
      }
  json += "]}";
  const Scene s = parseScene(json, "<test>", ".");
  for (bool warm : {true, false}) {
    const Stepped one = trajectory(s, soft(s, false, false, warm), 240);
    const Stepped eight = trajectory(s, soft(s, true, false, warm), 240);
    ASSERT_GT(eight.laneRuns, 0);
    ASSERT_EQ(one.hashes.size(), eight.hashes.size());
    for (size_t k = 0; k < one.hashes.size(); ++k)
      ASSERT_EQ(one.hashes[k], eight.hashes[k]) << (warm ? "warm" : "cold") << ", step " << k + 1;
  }
}

// Runs: the pyramid's are about twice its width (its rows' manifolds in a diagonal wavefront),
// not one a manifold (a chain) nor one for all (which would solve neighbours at once); and they
// fill the lanes: the groups are at most a fifth more than the larger of the runs (each at least
// one group) and the manifolds over eight. The levels (every ready manifold a run) took 97 groups
// for 414 manifolds in 77 runs on the 20-level pyramid, 292 for 1705 in 185 on the 40-level one.
TEST(Lanes, APyramidsRunsAreAboutTwiceItsWidthAndFillTheLanes) {
  struct Case {
    const char* scene;
    int minRuns, maxRuns;
  };
  for (const Case& c : {Case{"pyramid.json", 30, 100}, Case{"atlas/pyramid_40.json", 70, 250}}) {
    const Scene s = scene(c.scene);
    World w(s.model, soft(s, true, false, true), s.initial);
    for (int k = 0; k < 60; ++k) {
      const StepReport& r = w.step();
      ASSERT_TRUE(r.finite) << c.scene;
      if (k + 1 < 30) continue;  // settled into its contacts
      const std::string what = std::string(c.scene) + ", step " + std::to_string(k + 1);
      const int runs = r.solver.laneRuns, groups = r.solver.laneGroups;
      EXPECT_GE(runs, c.minRuns) << what;
      EXPECT_LE(runs, c.maxRuns) << what;
      const int least = std::max(runs, (r.manifolds + lanes::kLanes - 1) / lanes::kLanes);
      EXPECT_LE(groups, least * 6 / 5) << what << ": " << r.manifolds << " manifolds, " << runs << " runs";
    }
  }
}

// The three kernels (eight lanes an instruction, four, and four in pairs of two) give the same
// numbers, and the widest this processor runs is the one taken.
TEST(Lanes, TheKernelsAgree) {
  const Scene s = scene("pyramid.json");
  const SolverSettings st = soft(s, true, false, true);
  lanes::useKernel(&lanes::sse2Kernel());
  const Stepped baseline = trajectory(s, st, 30);
  ASSERT_GT(baseline.laneRuns, 0);
  int compared = 0;
  for (const auto& [supported, k] : {std::pair{lanes::avx2Supported(), &lanes::avx2Kernel()},
                                     std::pair{lanes::avx512Supported(), &lanes::avx512Kernel()}}) {
    if (!supported) continue;
    lanes::useKernel(k);
    EXPECT_EQ(baseline.hashes, trajectory(s, st, 30).hashes) << k->name;
    ++compared;
  }
  lanes::useKernel(nullptr);
  EXPECT_STREQ(lanes::kernel().name, lanes::avx512Supported() ? "avx512" : lanes::avx2Supported() ? "avx2" : "sse2");
  if (compared == 0) GTEST_SKIP() << "this processor has neither AVX2 nor AVX-512: only the baseline kernel ran";
}

namespace {

// Boxes on a 45° ramp, on the ground and on one another, and spheres: normals on both sides of
// tangentBasis's switch (|n.x| = 1/√3), one to four points a manifold, and points apart.
Scene rampScene() {
  std::string json = R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [10, 0.5, 10]}, "position": [0, -0.5, 0]},
      {"name": "ramp", "static": true, "shape": {"type": "box", "half_extents": [3, 0.5, 3]}, "position": [-5, 2, 0],
       "orientation": [0.9238795, 0, 0, 0.3826834]})";
  for (int i = 0; i < 12; ++i) {
    const double x = -6.2 + 0.9 * (i % 3), z = -1.5 + 1.2 * (i / 3);
    json += R"(, {"name": "r)" + std::to_string(i) + R"(", "shape": {"type": "box", "half_extents": [0.3, 0.2, 0.3]}, "position": [)" +
            std::to_string(x) + ", " + std::to_string(2.9 - (x + 5) + 0.05 * i) + ", " + std::to_string(z) +
            R"(], "orientation": [0.9238795, 0, 0, 0.3826834]})";
  }
  for (int i = 0; i < 10; ++i) {  // a leaning column on the ground
    const std::string shape = i % 3 == 2 ? "{\"type\": \"sphere\", \"radius\": 0.4}"
                                         : "{\"type\": \"box\", \"half_extents\": [0.4, 0.4, 0.4]}";
    json += ", {\"name\": \"g" + std::to_string(i) + "\", \"shape\": " + shape + ", \"position\": [" +
            std::to_string(1.0 + 0.3 * (i % 2)) + ", " + std::to_string(0.42 + 0.85 * i) + ", 0], \"orientation\": [" +
            std::to_string(std::cos(0.1 * i)) + ", 0, " + std::to_string(std::sin(0.1 * i)) + ", 0]}";
  }
  json += "]}";
  return parseScene(json, "<test>", ".");
}


// Lane l of row lanes `to` against row r (null: a zero row, +0 everywhere), the c0 or μ beside.
void expectLane(const lanes::RowLanes& to, int l, const Row* r, const std::string& what) {
  const auto expect = [&](double lane, double row, const char* field) {
    EXPECT_TRUE(sameBits(lane, row)) << what << " " << field << ": lanes " << lane << ", rows " << row;
  };
  for (int i = 0; i < 3; ++i) {
    expect(to.lin[i].x[l], r ? r->lin[i] : 0.0, "lin");
    expect(to.angA[i].x[l], r ? r->angA[i] : 0.0, "angA");
    expect(to.angB[i].x[l], r ? r->angB[i] : 0.0, "angB");
  }
  expect(to.effMass.x[l], r ? r->effMass : 0.0, "effMass");
  expect(to.lambda.x[l], r ? r->lambda : 0.0, "lambda");
  EXPECT_EQ(to.pushed.x[l], 0) << what;
}

// Group [first, first + 8) of cs's manifolds formulated by kernel k, as the fill does it, against
// formulateManifold's rows bit for bit (lanes not in use and held points: zero rows).
void expectGroupAsRows(const ConstraintSet& cs, const StepInputs& in, const lanes::Kernel& k, size_t first, double h,
                       const std::string& context) {
  lanes::ManifoldLanes definitions;
  lanes::Group g;
  g.count = static_cast<int>(std::min<size_t>(lanes::kLanes, cs.frictions.size() - first));
  const auto manifold = [&](int l) { return first + (l < g.count ? static_cast<size_t>(l) : 0); };
  for (int l = 0; l < lanes::kLanes; ++l) {
    const FrictionDef& fd = cs.frictions[manifold(l)];
    lanes::putMasses(g, l, in.mass[static_cast<size_t>(fd.a)], in.mass[static_cast<size_t>(fd.b)], l < g.count);
    lanes::gatherManifold(cs, manifold(l), l, definitions);
  }
  k.formulate(definitions, g, lanes::formulation(cs, h));
  for (int l = 0; l < lanes::kLanes; ++l) {
    const bool used = l < g.count;
    const FrictionDef& fd = cs.frictions[manifold(l)];
    Row rows[lanes::kMaxNormals + 3];
    FrictionCoupling coupling;
    cs.formulateManifold(manifold(l), rows, coupling);
    const std::string what = context + ", " + k.name + ", manifold " + std::to_string(manifold(l)) +
                             (used ? "" : " (lane not in use)");
    for (int q = 0; q < lanes::kMaxNormals; ++q) {
      const Row* r = used && q < fd.normalCount && rows[q].hi != 0 ? &rows[q] : nullptr;
      expectLane(g.normal[q], l, r, what + ", point " + std::to_string(q));
      EXPECT_TRUE(sameBits(g.normal[q].c0.x[l], r ? -r->bias * h : 0.0)) << what << ", point " << q << " c0";
    }
    for (int i = 0; i < 3; ++i) {
      const Row* r = used ? &rows[fd.normalCount + i] : nullptr;
      expectLane(g.friction[i], l, r, what + ", friction " + std::to_string(i));
      EXPECT_TRUE(sameBits(g.friction[i].mu.x[l], r ? r->hi : 0.0)) << what << ", friction " << i << " mu";
    }
    EXPECT_TRUE(sameBits(g.g10.x[l], used ? coupling.g10 : 0.0)) << what << " g10";
    EXPECT_TRUE(sameBits(g.g20.x[l], used ? coupling.g20 : 0.0)) << what << " g20";
    EXPECT_TRUE(sameBits(g.g21.x[l], used ? coupling.g21 : 0.0)) << what << " g21";
  }
}

}  // namespace

// The kernels formulate a group's manifolds (world contact frame, warm) as the set's own
// formulateManifold and finishRow do, to the last bit: J̌, m_eff, the warm-start λ (the tangential
// one carried onto this step's tangents), C⁰, μ and the friction couplings; lanes not in use, points
// a lane lacks and, without speculative contacts, points apart (which hold nothing: λ in [0, 0])
// are zero rows.
TEST(Lanes, TheKernelsFormulateAsTheRowsAre) {
  const Scene s = rampScene();
  const std::vector<const lanes::Kernel*> kernels = availableKernels();
  for (bool speculative : {true, false}) {
    SolverOverrides o = s.solver;
    o.set(&SolverSettings::algorithm, Algorithm::Soft);
    o.set(&SolverSettings::speculative, speculative);
    const SolverSettings st = resolve(o);
    ASSERT_TRUE(st.lanes && st.warmStart);
    ASSERT_EQ(st.contactFrame, ContactFrame::World);
    World w(s.model, st, s.initial);
    const double h = st.dt / st.substeps;
    int steep = 0, apart = 0, counts[lanes::kMaxNormals + 1] = {};
    for (int step = 0; step < 45; ++step) {
      w.step();
      const ConstraintSet& cs = w.constraints();
      ASSERT_TRUE(cs.contactRowsDeferred());
      const StepInputs in = stepInputs(w);  // the masses as the world's steppers have them (all awake)
      const std::string context = std::string(speculative ? "" : "not speculative, ") + "step " + std::to_string(step + 1);
      for (const lanes::Kernel* k : kernels)
        for (size_t first = 0; first < cs.frictions.size(); first += lanes::kLanes) {
          expectGroupAsRows(cs, in, *k, first, h, context);
          if (HasFailure()) return;
        }
      for (size_t m = 0; m < cs.frictions.size(); ++m) {
        const FrictionDef& fd = cs.frictions[m];
        steep += std::abs(fd.worldN.x()) >= 0.57735;
        ++counts[fd.normalCount];
        Row rows[lanes::kMaxNormals + 3];
        FrictionCoupling coupling;
        cs.formulateManifold(m, rows, coupling);
        for (int q = 0; q < fd.normalCount; ++q) apart += rows[q].bias < 0;
      }
    }
    // The cases the test is for were there.
    EXPECT_GT(steep, 0) << "no normal past tangentBasis's switch";
    EXPECT_GT(apart, 0) << "no point apart";
    EXPECT_GT(counts[1], 0) << "no one-point manifold";
    EXPECT_GT(counts[4], 0) << "no four-point manifold";
  }
}

// Without speculative contacts a point apart at the step's start holds nothing that step (its λ
// bounded to [0, 0]); in the lanes, which bound every normal to [0, ∞), it is a zero row. On the
// ramp the lanes give the one-manifold solve's trajectory, formulating in lanes (world frame) or
// each manifold on its own (the bodies' frame), warm and cold.
TEST(Lanes, PointsApartHoldNothingWithoutSpeculativeContacts) {
  const Scene s = rampScene();
  for (ContactFrame frame : {ContactFrame::World, ContactFrame::Bodies})
    for (bool warm : {true, false}) {
      const auto settings = [&](bool lanes) {
        SolverOverrides o = s.solver;
        o.set(&SolverSettings::algorithm, Algorithm::Soft);
        o.set(&SolverSettings::speculative, false);
        o.set(&SolverSettings::contactFrame, frame);
        o.set(&SolverSettings::lanes, lanes);
        o.set(&SolverSettings::warmStart, warm);
        return resolve(o);
      };
      const std::string what = std::string(frame == ContactFrame::World ? "world" : "bodies") + (warm ? " warm" : " cold");
      const Stepped one = trajectory(s, settings(false), 90), eight = trajectory(s, settings(true), 90);
      ASSERT_GT(eight.laneRuns, 0) << what;
      ASSERT_EQ(one.hashes.size(), eight.hashes.size()) << what;
      for (size_t k = 0; k < one.hashes.size(); ++k) ASSERT_EQ(one.hashes[k], eight.hashes[k]) << what << ", step " << k + 1;
    }
}

namespace {


// Two sets built from the same inputs, contacts formulated in lanes by kernel k and one manifold
// at a time: every row, friction coupling and contact block the same to the last bit.
void expectSameSets(const World& w, const SolverSettings& st, const lanes::Kernel& k, const std::string& context,
                    int& blocksChecked) {
  const StepInputs in = stepInputs(w);
  const double h = st.dt / st.substeps, scale = st.algorithm == Algorithm::A5 ? st.kappa : 1.0;
  ConstraintSet eight, one;
  one.formulateInLanes(false);
  lanes::useKernel(&k);
  eight.build(w.model(), w.manifolds(), in.poses, in.mass, st, h, scale);
  lanes::useKernel(nullptr);
  one.build(w.model(), w.manifolds(), in.poses, in.mass, st, h, scale);
  ASSERT_TRUE(eight.formulatedInLanes()) << context;
  ASSERT_FALSE(one.formulatedInLanes()) << context;
  const std::string what = context + ", " + k.name;
  ASSERT_EQ(eight.rows.size(), one.rows.size()) << what;
  for (size_t r = 0; r < one.rows.size(); ++r) expectSameRow(eight.rows[r], one.rows[r], what + ", row " + std::to_string(r));
  ASSERT_EQ(eight.couplings.size(), one.couplings.size()) << what;
  for (size_t c = 0; c < one.couplings.size(); ++c) {
    EXPECT_TRUE(sameBits(eight.couplings[c].g10, one.couplings[c].g10)) << what << ", coupling " << c;
    EXPECT_TRUE(sameBits(eight.couplings[c].g20, one.couplings[c].g20)) << what << ", coupling " << c;
    EXPECT_TRUE(sameBits(eight.couplings[c].g21, one.couplings[c].g21)) << what << ", coupling " << c;
  }
  ASSERT_EQ(eight.units.size(), one.units.size()) << what;
  ASSERT_EQ(eight.blocks.size(), one.blocks.size()) << what;
  for (size_t b = 0; b < one.blocks.size(); ++b) {
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        EXPECT_TRUE(sameBits(eight.blocks[b].K(i, j), one.blocks[b].K(i, j))) << what << ", block " << b << " K " << i << j;
        EXPECT_TRUE(sameBits(eight.blocks[b].invK(i, j), one.blocks[b].invK(i, j)))
            << what << ", block " << b << " invK " << i << j;
      }
    EXPECT_EQ(eight.blocks[b].lastMask, one.blocks[b].lastMask) << what << ", block " << b;
  }
  blocksChecked += static_cast<int>(one.blocks.size());
}

}  // namespace

// The rows build() stores are formulated eight manifolds at a time by every kernel as
// formulateManifold, finishRow and formBlock make them one at a time, to the last bit: in the
// bodies' frame with A5's κ-scaled M̌⁻¹J̌ᵀ and contact blocks (the 20-level pyramid's settings,
// speculative points or not, one to four points a manifold, normals past tangentBasis's switch),
// cold under A3, and in the world frame (the soft step one manifold at a time).
TEST(Lanes, StoredRowsAreFormulatedInLanesAsOneAtATime) {
  const Scene s = rampScene();
  const std::vector<const lanes::Kernel*> kernels = availableKernels();
  struct Case {
    const char* name;
    Algorithm algorithm;
    bool warm, blocks, speculative;
  };
  const Case cases[] = {
      {"a5 blocks", Algorithm::A5, true, true, true},
      {"a5 blocks not speculative", Algorithm::A5, true, true, false},
      {"a3 cold", Algorithm::A3, false, false, true},
      {"soft one by one", Algorithm::Soft, true, false, true},  // its lanes off: rows stored
  };
  for (const Case& c : cases) {
    SolverOverrides o = scene("pyramid.json").solver;  // κ 0.85, τ 0
    o.set(&SolverSettings::algorithm, c.algorithm);
    o.set(&SolverSettings::warmStart, c.warm);
    o.set(&SolverSettings::contactBlocks, c.blocks);
    o.set(&SolverSettings::speculative, c.speculative);
    if (c.algorithm == Algorithm::Soft) o.set(&SolverSettings::lanes, false);
    const SolverSettings st = resolve(o);
    ASSERT_EQ(st.contactFrame, c.algorithm == Algorithm::Soft ? ContactFrame::World : ContactFrame::Bodies) << c.name;
    World w(s.model, st, s.initial);
    int blocks = 0;
    for (int step = 0; step < 45; ++step) {
      w.step();
      if (step % 4 != 0 || w.manifolds().empty()) continue;
      for (const lanes::Kernel* k : kernels) {
        expectSameSets(w, st, *k, std::string(c.name) + ", step " + std::to_string(step + 1), blocks);
        if (HasFailure()) return;
      }
    }
    EXPECT_EQ(blocks > 0, c.blocks) << c.name << ": contact blocks checked " << blocks;
  }
}

namespace {

// What stepping two worlds side by side saw: the most runs a step of each solved in lanes, and
// whether the second's stored rows went uncompared (it stored none).
struct SideBySide {
  int one = 0, eight = 0;
  bool rowsSkipped = false;
};

// Worlds under settings `one` and `eight` stepped side by side: the same state hash after every
// step, the same impulses kept in the manifolds for the next step's warm start (and the contact
// blocks' last active sets), and the same stored rows field by field (λ and pushes for
// restitution, warm starting and overlays; A5's β̄ and bounds as its prologue scaled them), unless
// the second stores none (the soft step in lanes, warm and without joints, formulates its contact
// rows as it solves them; A5's lane groups hold them).
void stepSideBySide(const Scene& s, const SolverSettings& one, const SolverSettings& eight, int steps,
                    const std::string& what, SideBySide& runs) {
  World a(s.model, one, s.initial), b(s.model, eight, s.initial);
  for (int step = 1; step <= steps; ++step) {
    const StepReport& r = a.step();
    runs.one = std::max(runs.one, r.solver.laneRuns);
    runs.eight = std::max(runs.eight, b.step().solver.laneRuns);
    ASSERT_EQ(hashText(stateHash(a.state())), hashText(stateHash(b.state()))) << what << ", step " << step;
    ASSERT_EQ(a.manifolds().size(), b.manifolds().size()) << what << ", step " << step;
    for (size_t k = 0; k < a.manifolds().size(); ++k) {
      const Manifold &ma = a.manifolds()[k], &mb = b.manifolds()[k];
      const std::string at = what + ", step " + std::to_string(step) + ", manifold " + std::to_string(k);
      ASSERT_EQ(ma.count, mb.count) << at;
      for (int p = 0; p < ma.count; ++p) ASSERT_TRUE(sameBits(ma.points[p].lambda, mb.points[p].lambda)) << at;
      for (int i = 0; i < 3; ++i) ASSERT_TRUE(sameBits(ma.frictionImpulse[i], mb.frictionImpulse[i])) << at;
      ASSERT_TRUE(sameBits(ma.twistImpulse, mb.twistImpulse)) << at;
      ASSERT_EQ(ma.blockMask, mb.blockMask) << at;
    }
    const std::vector<Row>& rows = a.constraints().rows;
    runs.rowsSkipped |= b.constraints().contactRowsDeferred();
    if (!b.constraints().contactRowsDeferred()) {
      ASSERT_EQ(rows.size(), b.constraints().rows.size()) << what << ", step " << step;
      for (size_t q = 0; q < rows.size(); ++q)
        ASSERT_EQ(rowDifferences(b.constraints().rows[q], rows[q]), "") << what << ", step " << step << ", row " << q;
    }
    if (!r.finite) break;
  }
}

}  // namespace

// A5 sweeps the lanes build() lays out in the runs of the step's order (warm, contact blocks, one
// thread) with the numbers of its sweep one manifold at a time, to the last bit, on every kernel:
// on the pyramid (four-point blocks, the active-set search where neither none nor all push) and the
// ramp (one to four points: single rows beside blocks, normals past tangentBasis's switch), with
// τ 0 and τ 0.2 (friction's bias refreshed in the lanes between sub-steps), in the manifold order,
// without speculative points (held points), and with split impulses (the penetrations' part of β
// taken out of the rows the lanes start from) and restitution (every approach bounces).
TEST(Lanes, A5SweepsInLanesAsOneAtATime) {
  const std::vector<const lanes::Kernel*> kernels = availableKernels();
  struct Case {
    const char* name;
    double tau;
    ContactOrder order;
    bool speculative;
    bool split = false;
    double bounce = -1;  // the bodies' restitution, bouncing from any approach (-1: the scene's)
  };
  const Case cases[] = {
      {"pyramid.json's", 0, ContactOrder::Split, true},
      {"tau 0.2", 0.2, ContactOrder::Split, true},
      {"manifold order", 0, ContactOrder::Manifold, true},
      {"not speculative", 0, ContactOrder::Split, false},
      {"split impulse", 0.6, ContactOrder::Split, true, true},
      {"restitution", 0.2, ContactOrder::Split, true, false, 0.5},
  };
  const std::pair<const char*, Scene> scenes[] = {{"pyramid", scene("pyramid.json")}, {"ramp", rampScene()}};
  for (const auto& [sceneName, original] : scenes)
    for (const Case& c : cases) {
      Scene s = original;
      if (c.bounce >= 0)
        for (Body& b : s.model.bodies) b.restitution = c.bounce;
      const auto settings = [&](bool lanes) {
        SolverOverrides o = scene("pyramid.json").solver;  // a5, κ 0.85, warm, contact blocks
        o.set(&SolverSettings::tau, c.tau);
        o.set(&SolverSettings::contactOrder, c.order);
        o.set(&SolverSettings::speculative, c.speculative);
        o.set(&SolverSettings::splitImpulse, c.split);
        if (c.bounce >= 0) o.set(&SolverSettings::restitutionThreshold, 0.0);
        o.set(&SolverSettings::lanes, lanes);
        return resolve(o);
      };
      for (const lanes::Kernel* k : kernels) {
        const std::string what = std::string(sceneName) + ", " + c.name + ", " + k->name;
        lanes::useKernel(k);
        SideBySide runs;
        stepSideBySide(s, settings(false), settings(true), 60, what, runs);
        lanes::useKernel(nullptr);
        if (HasFatalFailure()) return;
        ASSERT_EQ(runs.one, 0) << what;
        ASSERT_GT(runs.eight, 0) << what;
        // The groups are the contact rows' only copy unless split impulses or restitution read
        // the rows after the sweeps.
        ASSERT_EQ(runs.rowsSkipped, !c.split && c.bounce < 0) << what;
      }
    }
}

// Lanes or not, the same trajectory and stored rows under any settings: every setting of the
// schema that A5 or the soft step reads set at random (flags and choices anywhere, numbers at half,
// one and one and a half times their default where their range allows), on the pyramid and the
// ramp, 30 steps. Settings the chosen cases above leave out are where a lane path can miss a rule
// of the rows (split impulses were, until 2026-12-06). Warm starting and contact blocks are on in
// two draws of three, so that A5's lanes are taken often.
TEST(Lanes, RandomSettingsTakeTheSameStepsInLanes) {
  std::mt19937_64 random(20261206);
  const std::pair<const char*, Scene> scenes[] = {{"pyramid", scene("pyramid.json")}, {"ramp", rampScene()}};
  int inLanes = 0, draws = 0;
  for (const Algorithm algorithm : {Algorithm::A5, Algorithm::Soft})
    for (int draw = 0; draw < 24; ++draw) {
      DrawnSettings drawn = drawSettings(algorithm, random, {"lanes", "threads", "dt"}, {"warm_start", "contact_blocks"});
      SolverOverrides& o = drawn.overrides;
      const std::string what = std::string(algorithmName(algorithm)) + " draw " + std::to_string(draw) + ": " + drawn.text;
      SolverSettings lanesOff, lanesOn;
      try {
        o.set(&SolverSettings::lanes, false);
        lanesOff = resolve(o);
        o.set(&SolverSettings::lanes, true);
        lanesOn = resolve(o);
      } catch (const std::invalid_argument&) {
        continue;  // a combination the schema refuses (a soft stiffness above the sub-steps' rate)
      }
      for (const auto& [sceneName, s] : scenes) {
        ++draws;
        SideBySide runs;
        ASSERT_NO_FATAL_FAILURE(stepSideBySide(s, lanesOff, lanesOn, 30, std::string(sceneName) + ", " + what, runs));
        inLanes += runs.eight > 0;
      }
    }
  // The draws reach the lanes: most of them, not a lucky few.
  EXPECT_GT(inLanes, draws / 3) << inLanes << " of " << draws << " draws solved in lanes";
}
