// The soft step's lanes (physics/steppers/soft_lanes.h): eight manifolds solved at once give the
// numbers of one at a time, to the last bit, in the step's order (its runs) and by colours, warm
// and cold, with joints re-formulated between sub-steps; and the AVX-512, AVX2 and baseline
// kernels give the same numbers.
#include "physics/scene_file.h"
#include "physics/state_hash.h"
#include "physics/steppers/soft_lanes.h"
#include "physics/world.h"

#include <gtest/gtest.h>

#include <algorithm>
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
