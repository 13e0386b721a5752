// The step's threads (SolverSettings::threads): a trajectory is the same to the last bit on any
// number of threads, under every algorithm, on the scenes where the work is shared out most (a
// pyramid: one island; a pile: a thousand boxes; the ragdoll pile: joints before the contacts),
// with the soft step's contacts in the step's order and by colours. Slow: out of the sanitizer
// pass (tests/test_parallel.cpp holds the pool itself there).
#include "physics/scene_file.h"
#include "physics/state_hash.h"
#include "physics/world.h"

#include <gtest/gtest.h>

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

}  // namespace

TEST(Threads, TrajectoriesAreBitIdenticalForAnyNumberOfThreads) {
  struct Case {
    const char* scene;
    int steps;
  };
  for (const Case& c : {Case{"pyramid.json", 40}, Case{"pile.json", 40}, Case{"ragdoll_pile.json", 40}}) {
    const Scene s = loadScene(std::string(SUBSTEP_SOURCE_DIR "/assets/scenes/") + c.scene);
    std::vector<std::pair<Algorithm, bool>> methods;  // (algorithm, the soft step by colours)
    for (Algorithm a : kAlgorithms) methods.emplace_back(a, false);
    methods.emplace_back(Algorithm::Soft, true);
    for (const auto& [a, colours] : methods) {
      SolverOverrides o = s.solver;
      o.set(&SolverSettings::algorithm, a);
      if (colours) o.set(&SolverSettings::colours, true);
      const SolverSettings st = resolve(o);
      const std::vector<std::string> one = trajectory(s, st, 1, c.steps);
      for (int threads : {2, 3}) {
        const std::vector<std::string> many = trajectory(s, st, threads, c.steps);
        const std::string what = std::string(c.scene) + " " + algorithmName(a) + (colours ? " colours" : "") + " on " +
                                 std::to_string(threads) + " threads";
        ASSERT_EQ(one.size(), many.size()) << what;
        for (size_t k = 0; k < one.size(); ++k) ASSERT_EQ(one[k], many[k]) << what << ", step " << k + 1;
      }
    }
  }
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
