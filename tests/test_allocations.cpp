// No allocation inside a step once a scene has settled: every buffer the pipeline uses (pairs,
// manifolds, rows, units, blocks, sub-step velocities) keeps its capacity from step to step.
// The count is of every operator new in this process while World::step runs.
#include "physics/scene_file.h"
#include "physics/step_arrays.h"
#include "physics/world.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cctype>
#include <cstdlib>
#include <new>
#include <sys/resource.h>
#include <string>
#include <vector>

namespace {
std::atomic<long> gAllocations{0};
std::atomic<bool> gCounting{false};
}  // namespace

// Replaced by malloc and free; g++ sees gtest's `new` paired with our `free` once inlined and
// warns of a mismatch that is not one.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t n) {
  if (gCounting.load(std::memory_order_relaxed)) gAllocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
// Over-aligned types (the worker pool's cache-line members) come through these.
void* operator new(std::size_t n, std::align_val_t al) {
  if (gCounting.load(std::memory_order_relaxed)) gAllocations.fetch_add(1, std::memory_order_relaxed);
  const std::size_t a = static_cast<std::size_t>(al);
  if (void* p = std::aligned_alloc(a, (n + a - 1) / a * a)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

using namespace substep;

namespace {

struct Case {
  const char* scene;
  const char* algorithm;  // "" for the scene's own settings
};

std::string caseName(const ::testing::TestParamInfo<Case>& i) {
  std::string s = std::string(i.param.scene) + "_" + (*i.param.algorithm ? i.param.algorithm : "scene");
  for (char& c : s)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return s;
}

class SettledStep : public ::testing::TestWithParam<Case> {};

}  // namespace

TEST_P(SettledStep, AllocatesNothing) {
  const Case& c = GetParam();
  const Scene scene = loadScene(std::string(SUBSTEP_SOURCE_DIR "/assets/scenes/") + c.scene + ".json");
  SolverOverrides o = scene.solver;
  if (*c.algorithm) o.set(&SolverSettings::algorithm, *parseAlgorithm(c.algorithm));
  World world(scene.model, resolve(o), scene.initial);
  for (int k = 0; k < 180; ++k) ASSERT_TRUE(world.step().finite);  // 3 s: settled
  gAllocations = 0;
  gCounting = true;
  bool finite = true;
  for (int k = 0; k < 100; ++k) finite = finite && world.step().finite;
  gCounting = false;
  ASSERT_TRUE(finite);
  EXPECT_EQ(gAllocations.load(), 0) << "allocations in 100 settled steps of " << c.scene;
}

// Every pair of the pyramid, the stack, the chain and the ragdoll pile has a closed form (boxes by
// separating axes, spheres and capsules by core segments): FCL, which allocates on every query
// (libccd's simplices), is not called once they settle. Before the closed forms of 2026-12-02 the
// pyramid under A2 (rocking boxes overlap) made 71 063 allocations in 100 steps, the stack 8 and
// the ragdoll pile 61 315.
INSTANTIATE_TEST_SUITE_P(Scenes, SettledStep,
                         ::testing::Values(Case{"pyramid", ""}, Case{"pyramid", "a2"}, Case{"pyramid", "a3"},
                                           Case{"pyramid", "a4"}, Case{"pyramid", "soft"}, Case{"stack", ""},
                                           Case{"chain", ""}, Case{"ragdoll_pile", ""}),
                         caseName);

// The step's large arrays (physics/step_arrays.h): a settling scene's contacts grow by a few per
// cent after its first step (the 100-level pyramid's points from 40 000 to 41 200), which must
// not reallocate them; grown as std::vector grows them, its manifolds, contact definitions and
// lane groups were reallocated to twice their size at its sixth step, every element copied: 90 ms
// in one step (docs/benchmarks.md, "The large arrays' growth").
TEST(StepArrays, AFewPerCentMoreTakesNoNewStorage) {
  std::vector<double> v;
  resizeRewritten(v, 40000);
  const double* storage = v.data();
  gAllocations = 0;
  gCounting = true;
  resizeRewritten(v, 41200);
  resizeRewritten(v, 39000);
  resizeRewritten(v, 50000);
  gCounting = false;
  EXPECT_EQ(gAllocations.load(), 0);
  EXPECT_EQ(v.data(), storage);
  EXPECT_EQ(v.size(), 50000u);
}

// Beyond its room an array is taken anew, the old elements not copied (the step writes every one),
// and at least twice as large, so that an array that keeps growing (a pile falling into place)
// is not taken anew at every step.
TEST(StepArrays, BeyondItsRoomTwiceAsMuchAndNothingCopied) {
  std::vector<double> v;
  resizeRewritten(v, 100);
  for (double& x : v) x = 7;
  const size_t room = v.capacity();
  resizeRewritten(v, room + 1);
  EXPECT_GE(v.capacity(), 2 * room);
  EXPECT_EQ(v.size(), room + 1);
  for (size_t k = 0; k < v.size(); ++k) ASSERT_EQ(v[k], 0.0) << "element " << k << " copied, not value-initialised";
}

// New storage is touched page by page on the pool's threads before its elements are constructed
// on the calling thread, which then takes a share of the page faults, not all of them (counted by
// getrusage, the calling thread's against the process's): 64 MB, 16 384 pages, on a pool of two.
// Where transparent huge pages are always on, 64 MB is a few dozen faults: nothing to test.
TEST(StepArrays, NewStorageFaultedInOnThePoolsThreads) {
  WorkerPool two(2);
  if (two.threads() < 2) GTEST_SKIP() << "the system gave one thread";
  const auto faults = [](int who) {
    rusage ru{};
    getrusage(who, &ru);
    return ru.ru_minflt;
  };
  std::vector<double> v;
  const size_t n = (size_t{64} << 20) / sizeof(double) * 4 / 5;  // and a quarter more: 64 MB
  const long callerBefore = faults(RUSAGE_THREAD), allBefore = faults(RUSAGE_SELF);
  resizeRewritten(v, n, two);
  const long caller = faults(RUSAGE_THREAD) - callerBefore, all = faults(RUSAGE_SELF) - allBefore;
  if (all < 1000) GTEST_SKIP() << "64 MB faulted in " << all << " faults (transparent huge pages?): few to share out";
  EXPECT_LT(static_cast<double>(caller), 0.8 * static_cast<double>(all))
      << "the calling thread took " << caller << " of the " << all << " faults";
  EXPECT_EQ(v.size(), n);
  for (size_t k = 0; k < v.size(); k += 4096) ASSERT_EQ(v[k], 0.0);
}
