// The step's threads (SolverSettings::threads): a trajectory is the same to the last bit on any
// number of threads, under every algorithm, on the scenes where the work is shared out most (a
// pyramid: one island; a pile: a thousand boxes; the ragdoll pile: joints before the contacts),
// with the soft step's contacts in the step's order and by colours. Slow: out of the sanitizer
// pass (tests/test_parallel.cpp holds the pool itself there).
#include "physics/parallel.h"
#include "physics/scene_file.h"
#include "physics/state_hash.h"
#include "physics/world.h"
#include "random_settings.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

using namespace substep;

namespace {

// The state's hash after every step, or the refusal's text.
std::vector<std::string> trajectory(const Scene& s, SolverSettings st, int threads, int steps) {
  st.threads = threads;
  std::vector<std::string> out;
  try {
    World w(s.model, st, s.initial);
    for (int k = 0; k < steps; ++k) {
      const StepReport& r = w.step();
      out.push_back(hashText(stateHash(w.state())) + (r.finite ? "" : " " + r.problem));
      if (!r.finite) break;
    }
  } catch (const std::exception& e) {
    out.push_back(std::string("refused: ") + e.what());
  }
  return out;
}

// "" when two trajectories agree step by step, else the first step where they part.
std::string firstDifference(const std::vector<std::string>& a, const std::vector<std::string>& b) {
  for (size_t k = 0; k < std::min(a.size(), b.size()); ++k)
    if (a[k] != b[k]) return "step " + std::to_string(k + 1) + ": " + a[k] + " against " + b[k];
  if (a.size() != b.size()) return std::to_string(a.size()) + " steps against " + std::to_string(b.size());
  return "";
}

// What the tests step each scene under: every algorithm, and the soft step by colours.
struct Method {
  Algorithm algorithm;
  bool colours;
};
std::vector<Method> methods() {
  std::vector<Method> out;
  for (Algorithm a : kAlgorithms) out.push_back({a, false});
  out.push_back({Algorithm::Soft, true});
  return out;
}

// The scene's own settings under method m.
SolverOverrides methodSettings(const Scene& s, const Method& m) {
  SolverOverrides o = s.solver;
  o.set(&SolverSettings::algorithm, m.algorithm);
  if (m.colours) o.set(&SolverSettings::colours, true);
  return o;
}
std::string methodName(const Method& m) { return std::string(algorithmName(m.algorithm)) + (m.colours ? " colours" : ""); }

}  // namespace

TEST(Threads, TrajectoriesAreBitIdenticalForAnyNumberOfThreads) {
  struct Case {
    const char* scene;
    int steps;
  };
  for (const Case& c : {Case{"pyramid.json", 40}, Case{"pile.json", 40}, Case{"ragdoll_pile.json", 40}}) {
    const Scene s = loadScene(std::string(SUBSTEP_SOURCE_DIR "/assets/scenes/") + c.scene);
    for (const Method& m : methods()) {
      const SolverSettings st = resolve(methodSettings(s, m));
      const std::vector<std::string> one = trajectory(s, st, 1, c.steps);
      for (int threads : {2, 3})
        ASSERT_EQ(firstDifference(one, trajectory(s, st, threads, c.steps)), "")
            << c.scene << " " << methodName(m) << " on " << threads << " threads";
    }
  }
}

// An island too large to go to one thread whole: A5 shares its sweeps out unit by unit, each unit
// solved once the units before it on its bodies are (UnitLevels), from 2048 units (the stepper's
// kLevelled). The 40-level pyramid is one island of some 3300 units; under pyramid.json's A5
// settings without the lanes and under A5's defaults (τ > 0: the rows' biases refreshed between
// sub-steps, on the threads too) it steps the same on one, two and three threads.
TEST(Threads, AnIslandSweptUnitByUnitOnTheThreadsStepsTheSame) {
  const Scene s = loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/atlas/pyramid_40.json");
  for (const char* spec : {"a5:n=4:m=1:kappa=0.85:tau=0:warm=on:cblock=on", "a5"}) {
    SolverSettings st = resolve(s.solver.merged(expandMethodSpec(spec)[0].overrides));
    st.lanes = false;  // in lanes A5 schedules its lane groups instead (the next test)
    {  // the case this test is for
      SolverSettings shared = st;
      shared.threads = 2;
      World w(s.model, shared, s.initial);
      w.step();
      ASSERT_EQ(w.constraints().islandCount(), 1) << spec;
      ASSERT_GE(w.constraints().units.size(), 2048u) << spec;
    }
    const std::vector<std::string> one = trajectory(s, st, 1, 30);
    for (int threads : {2, 3})
      ASSERT_EQ(firstDifference(one, trajectory(s, st, threads, 30)), "") << spec << " on " << threads << " threads";
  }
}

// Lane groups by OrderedSchedule on more threads: each group on its thread once the groups before it
// on its moving bodies are done, in every pass over them (A5, where the last step was mostly one
// island: its warm start and every phase of its sweeps; the soft step, where its runs are short:
// its warm start, solve and relax). On the 40-level pyramid under pyramid.json's settings, A5 with
// τ 0 and 0.2 (the friction rows' biases refreshed in the lanes, on the threads), and the soft
// step: the same steps on one, two and three threads.
TEST(Threads, LaneGroupsScheduledOnTheThreadsStepTheSame) {
  const Scene s = loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/atlas/pyramid_40.json");
  for (const char* spec : {"a5:n=4:m=1:kappa=0.85:tau=0:warm=on:cblock=on", "a5:n=4:m=1:kappa=0.85:tau=0.2:warm=on:cblock=on", "soft"}) {
    const SolverSettings st = resolve(s.solver.merged(expandMethodSpec(spec)[0].overrides));
    {  // the case this test is for: the second step on, in lanes by the schedule
      SolverSettings shared = st;
      shared.threads = 2;
      World w(s.model, shared, s.initial);
      w.step();
      const StepReport& r = w.step();
      ASSERT_GT(r.solver.laneGroups, 100) << spec;
      ASSERT_TRUE(r.solver.laneScheduled) << spec;
    }
    const std::vector<std::string> one = trajectory(s, st, 1, 30);
    for (int threads : {2, 3})
      ASSERT_EQ(firstDifference(one, trajectory(s, st, threads, 30)), "") << spec << " on " << threads << " threads";
  }
}

// Lane groups in parts of whole islands on more threads: where the last step was many islands (the
// pile's columns), A5 asks for its groups laid out in parts of whole islands, each part's in its own runs,
// and each thread sweeps the parts it takes through every sub-step with no wait on another. On
// pile.json under pyramid.json's settings, with τ 0 and 0.2 (the friction rows' biases refreshed
// in the lanes, each part its own), the same steps on one, two and three threads.
TEST(Threads, LaneGroupsInPartsOfWholeIslandsStepTheSame) {
  const Scene s = loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/pile.json");
  for (const char* spec : {"a5:n=4:m=1:kappa=0.85:tau=0:warm=on:cblock=on", "a5:n=4:m=1:kappa=0.85:tau=0.2:warm=on:cblock=on"}) {
    const SolverSettings st = resolve(s.solver.merged(expandMethodSpec(spec)[0].overrides));
    {  // the case this test is for: once the first columns have landed (the ninth step), in lanes in parts
      SolverSettings shared = st;
      shared.threads = 2;
      World w(s.model, shared, s.initial);
      int inParts = 0;
      for (int k = 0; k < 60; ++k) {
        const StepReport& r = w.step();
        if (r.solver.laneGroups == 0) continue;
        ASSERT_GT(r.solver.laneParts, 2) << spec << ", step " << k + 1;
        ASSERT_FALSE(r.solver.laneScheduled) << spec << ", step " << k + 1;
        ++inParts;
      }
      ASSERT_GT(inParts, 45) << spec << ": steps with the pile's groups in parts (of 60)";
    }
    const std::vector<std::string> one = trajectory(s, st, 1, 60);
    for (int threads : {2, 3})
      ASSERT_EQ(firstDifference(one, trajectory(s, st, threads, 60)), "") << spec << " on " << threads << " threads";
  }
}

// Threads take a job's blocks in whatever order they ask for them, so a block that reads what
// another block of its job writes gives a step that depends on the race. Taken last first on one
// thread (WorkerPool::takeBlocksLastFirst), every such read comes before the write: the scenes and
// methods above, in either contact frame, must step the same to the last bit. It found the lanes'
// formulation reading the first manifold's contact frame from every block of build()'s definitions.
TEST(Threads, BlocksTakenInAnyOrderGiveTheSameSteps) {
  struct LastFirst {
    LastFirst() { WorkerPool::takeBlocksLastFirst(true); }
    ~LastFirst() { WorkerPool::takeBlocksLastFirst(false); }
  };
  for (const char* scene : {"pyramid.json", "pile.json", "ragdoll_pile.json"}) {
    const Scene s = loadScene(std::string(SUBSTEP_SOURCE_DIR "/assets/scenes/") + scene);
    for (const Method& m : methods())
      for (ContactFrame frame : {ContactFrame::Bodies, ContactFrame::World}) {
        SolverOverrides o = methodSettings(s, m);
        o.set(&SolverSettings::contactFrame, frame);
        const SolverSettings st = resolve(o);
        const std::vector<std::string> inOrder = trajectory(s, st, 1, 20);
        std::vector<std::string> lastFirst;
        {
          const LastFirst reversed;
          lastFirst = trajectory(s, st, 1, 20);
        }
        ASSERT_EQ(firstDifference(inOrder, lastFirst), "")
            << scene << " " << methodName(m) << (frame == ContactFrame::World ? ", world frame" : ", bodies' frame");
      }
  }
}

// Any settings, not only the scenes' own: every setting an algorithm reads drawn at random
// (tests/random_settings.h), eight draws for each of A2-A5 and the soft step, on the pyramid and on
// the ragdoll pile (joints), 20 steps on one and on two threads.
TEST(Threads, RandomSettingsTakeTheSameStepsOnAnyNumberOfThreads) {
  std::mt19937_64 random(20261207);
  const std::pair<const char*, Scene> scenes[] = {
      {"pyramid", loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/pyramid.json")},
      {"ragdoll_pile", loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/ragdoll_pile.json")}};
  int stepped = 0;
  for (Algorithm a : {Algorithm::A2, Algorithm::A3, Algorithm::A4, Algorithm::A5, Algorithm::Soft})
    for (int draw = 0; draw < 8; ++draw) {
      const DrawnSettings drawn = drawSettings(a, random, {"threads", "dt"});
      SolverSettings st;
      try {
        st = resolve(drawn.overrides);
      } catch (const std::invalid_argument&) {
        continue;  // a combination the schema refuses
      }
      for (const auto& [name, s] : scenes) {
        const std::vector<std::string> one = trajectory(s, st, 1, 20);
        EXPECT_EQ(one, trajectory(s, st, 2, 20)) << name << ", " << algorithmName(a) << " draw " << draw << ": " << drawn.text;
        stepped += one.size() == 20;
      }
    }
  EXPECT_GT(stepped, 60) << "draws stepped 20 steps (of 80)";
}

// Sleeping bodies are static to the solve: the soft step's colours leave them out, and an island
// that falls asleep or wakes does so at the same step on any number of threads.
TEST(Threads, SleepingIsTheSameForAnyNumberOfThreads) {
  const Scene s = loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/pyramid.json");
  for (const auto& [a, colours] : {std::pair{Algorithm::Soft, true}, std::pair{Algorithm::Soft, false}, std::pair{Algorithm::A5, false}}) {
    SolverOverrides o = s.solver;
    o.set(&SolverSettings::algorithm, a);
    o.set(&SolverSettings::sleep, true);
    if (colours) o.set(&SolverSettings::colours, true);
    const SolverSettings st = resolve(o);
    EXPECT_EQ(trajectory(s, st, 1, 120), trajectory(s, st, 2, 120)) << algorithmName(a) << (colours ? " colours" : "");
  }
}

// A step refuses a diverged state naming its first bad body by index, whatever the threads (the
// check runs per block of 1024 bodies): of 3000 spheres far apart, s1500 and s2900 move beyond
// 1e6 m/s (3000 km/s, an impulse), in different blocks; on one thread and on three the step names
// s1500 and its speed.
TEST(Threads, ADivergedStateNamesItsFirstBadBodyOnAnyThreads) {
  std::string json = R"({"gravity": [0, 0, 0], "bodies": [)";
  for (int i = 0; i < 3000; ++i) {
    json += (i ? "," : "") + std::string(R"({"name": "s)") + std::to_string(i) +
            R"(", "shape": {"type": "sphere", "radius": 0.5}, "position": [)" + std::to_string(3 * i) + ", 0, 0]}";
  }
  json += "]}";
  const Scene s = parseScene(json, "<test>", ".");
  for (const int threads : {1, 3}) {
    SolverOverrides o = s.solver;
    o.set(&SolverSettings::algorithm, Algorithm::Soft);
    o.set(&SolverSettings::threads, threads);
    const SolverSettings st = resolve(o);
    World w(s.model, st, s.initial);
    for (const int i : {2900, 1500}) {  // through the centre: no spin; far beyond what a scene file takes
      const Body& b = s.model.bodies[static_cast<size_t>(i)];
      w.applyImpulse(i, Vec3(3e6 / b.invMass, 0, 0), s.initial.bodies[static_cast<size_t>(i)].x);
    }
    const StepReport& r = w.step();
    EXPECT_FALSE(r.finite) << threads << " threads";
    EXPECT_EQ(r.problem.rfind("body \"s1500\" has a speed beyond 1e6 m/s or rad/s (3000000", 0), 0u)
        << threads << " threads: " << r.problem;
  }
}
