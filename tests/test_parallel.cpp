// The step's worker pool (physics/parallel.h): every block handed out once, on every thread
// count, job after job; a thread starts on its own share of the blocks; an exception in a block
// reaches the caller; a Busy keeps the workers awake between jobs; OrderedSchedule solves each
// body's items in their order.
#include "physics/parallel.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

using namespace substep;

TEST(WorkerPool, EveryBlockOnceOnEveryThreadCount) {
  for (int threads : {1, 2, 3, 8}) {
    WorkerPool pool(threads);
    for (size_t blocks : {0u, 1u, 2u, 7u, 1000u}) {
      std::vector<std::atomic<int>> seen(blocks);
      std::atomic<int> badThread{0};
      pool.forBlocks(blocks, [&](size_t b, int t) {
        seen[b].fetch_add(1);
        if (t < 0 || t >= threads) badThread.fetch_add(1);
      });
      for (size_t b = 0; b < blocks; ++b) ASSERT_EQ(seen[b].load(), 1) << threads << " threads, block " << b;
      EXPECT_EQ(badThread.load(), 0);
    }
    // Ranges cover [0, count) exactly, and jobs follow one another without losing any.
    for (int round = 0; round < 200; ++round) {
      std::atomic<long> sum{0};
      pool.forRange(1001, 16, [&](size_t first, size_t last, int) {
        long s = 0;
        for (size_t i = first; i < last; ++i) s += static_cast<long>(i);
        sum.fetch_add(s);
      });
      ASSERT_EQ(sum.load(), 1000L * 1001 / 2) << threads << " threads, round " << round;
    }
  }
}

// Two threads, 100 blocks: the caller's share is blocks 0-49, the worker's 50-99. A thread
// works through its own share before it takes what is left of the other's, so whenever the
// worker joins, the first block it gets is one of its own share (with one counter for all it would
// get the block after the caller's first few, near 0).
TEST(WorkerPool, EachThreadStartsOnItsOwnShare) {
  WorkerPool pool(2);
  if (pool.threads() < 2) GTEST_SKIP() << "the system gave one thread";
  int workerRounds = 0;
  for (int round = 0; round < 5; ++round) {
    std::vector<int> order[2];
    pool.forBlocks(100, [&](size_t b, int t) {
      order[t].push_back(static_cast<int>(b));  // each thread appends to its own list only
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    });
    if (!order[1].empty()) {
      EXPECT_GE(order[1].front(), 50) << "round " << round;
    }
    EXPECT_EQ(order[0].size() + order[1].size(), 100u);
    workerRounds += !order[1].empty();
  }
  EXPECT_GT(workerRounds, 0) << "the worker joined none of five 20 ms jobs: nothing was checked";
}

TEST(WorkerPool, ABlockThatThrowsIsRethrownToTheCaller) {
  WorkerPool pool(2);
  EXPECT_THROW(pool.forBlocks(64,
                              [](size_t b, int) {
                                if (b == 37) throw std::runtime_error("block 37");
                              }),
               std::runtime_error);
  // The pool still works afterwards.
  std::atomic<int> n{0};
  pool.forBlocks(10, [&](size_t, int) { n.fetch_add(1); });
  EXPECT_EQ(n.load(), 10);
}

// Between two jobs a worker spins a while and then sleeps, unless a Busy lives (World::step holds
// one): then it waits awake however long the caller works alone, and the next job finds it
// there instead of waking it (10-100 µs on this project's virtual machine, at times milliseconds).
TEST(WorkerPool, ABusyKeepsTheWorkersAwakeBetweenJobs) {
  if (std::thread::hardware_concurrency() < 2) GTEST_SKIP() << "one core: a pool of two sleeps as before";
  using Clock = std::chrono::steady_clock;
  WorkerPool pool(2);
  // Jobs until the worker runs: one asleep since the pool started is woken by the next job, and
  // a virtual machine has taken milliseconds to run it again.
  const auto awaken = [&] {
    const auto until = Clock::now() + std::chrono::seconds(5);
    do pool.forBlocks(2, [](size_t, int) {});
    while (pool.sleeping() > 0 && Clock::now() < until);
    return pool.sleeping() == 0;
  };
  const auto sleptWithin = [&](std::chrono::milliseconds gap) {
    const auto until = Clock::now() + gap;
    while (Clock::now() < until)
      if (pool.sleeping() > 0) return true;
    return false;
  };
  {
    const WorkerPool::Busy busy(pool);
    ASSERT_TRUE(awaken()) << "the worker never ran";
    EXPECT_FALSE(sleptWithin(std::chrono::milliseconds(50))) << "asleep while a Busy lived";
  }
  ASSERT_TRUE(awaken()) << "the worker never ran";
  EXPECT_TRUE(sleptWithin(std::chrono::milliseconds(2000))) << "awake two seconds after the last Busy ended";
  // Jobs under a Busy again: every block still done once.
  const WorkerPool::Busy busy(pool);
  std::atomic<int> n{0};
  pool.forBlocks(100, [&](size_t, int) { n.fetch_add(1); });
  EXPECT_EQ(n.load(), 100);
}

// OrderedSchedule: random items over a few bodies (so that most items follow others), in runs of
// three (which only say which thread's list each item is on): on any number of threads, pass
// after pass, each body's items are solved in the items' order, each once. An item solved before
// its predecessors are done would show in a body's list out of order.
TEST(OrderedSchedule, EachBodysItemsInTheirOrderOnAnyNumberOfThreads) {
  static constexpr size_t kItems = 600, kBodies = 40;
  std::mt19937 rng(7);
  std::vector<std::vector<int>> bodiesOf(kItems);
  for (std::vector<int>& b : bodiesOf) {
    const int count = 1 + static_cast<int>(rng() % 4);
    for (int k = 0; k < count; ++k) {
      const int body = static_cast<int>(rng() % kBodies);
      if (std::find(b.begin(), b.end(), body) == b.end()) b.push_back(body);
    }
  }
  std::vector<std::vector<int>> serial(kBodies);
  for (size_t item = 0; item < kItems; ++item)
    for (int body : bodiesOf[item]) serial[static_cast<size_t>(body)].push_back(static_cast<int>(item));
  for (int threads : {1, 2, 3, 8}) {
    WorkerPool pool(threads);
    OrderedSchedule schedule;
    schedule.build(
        kItems, kBodies, pool.threads(),
        [&](size_t item, auto follow) {
          for (int body : bodiesOf[item]) follow(body);
        },
        [](size_t item) { return std::pair<size_t, size_t>(item / 3 * 3, std::min(kItems, item / 3 * 3 + 3)); });
    for (int pass = 0; pass < 3; ++pass) {
      std::vector<std::vector<int>> solved(kBodies);
      std::atomic<int> calls{0};
      auto f = [&](size_t first, size_t last, int) {
        for (size_t item = first; item < last; ++item) {
          for (int body : bodiesOf[item]) solved[static_cast<size_t>(body)].push_back(static_cast<int>(item));
          for (volatile int spin = 0; spin < 200; spin = spin + 1) {  // time for the other threads to run ahead
          }
        }
        calls.fetch_add(1);
      };
      schedule.run(pool, f);
      ASSERT_EQ(calls.load(), static_cast<int>(kItems)) << threads << " threads, pass " << pass;
      for (size_t body = 0; body < kBodies; ++body)
        ASSERT_EQ(solved[body], serial[body]) << threads << " threads, pass " << pass << ", body " << body;
    }
  }
}

// An item that throws: the pass stops (the items after it would wait for it for ever) and the
// pool rethrows to the caller; the schedule runs again afterwards. Also an item that names a body
// twice (it must not wait for itself).
TEST(OrderedSchedule, AnItemThatThrowsIsRethrownAndNothingWaitsForIt) {
  for (int threads : {1, 2, 3}) {
    WorkerPool pool(threads);
    OrderedSchedule schedule;
    constexpr size_t kItems = 200;
    schedule.build(
        kItems, 10, pool.threads(),
        [](size_t item, auto follow) {
          follow(static_cast<int>(item % 10));
          follow(static_cast<int>(item % 10));
        },
        [](size_t item) { return std::pair<size_t, size_t>(item, item + 1); });
    std::atomic<int> calls{0};
    auto throwing = [&](size_t first, size_t, int) {
      calls.fetch_add(1);
      if (first == 50) throw std::runtime_error("item 50");
    };
    EXPECT_THROW(schedule.run(pool, throwing), std::runtime_error) << threads << " threads";
    EXPECT_LT(calls.load(), static_cast<int>(kItems)) << threads << " threads";
    calls = 0;
    auto counting = [&](size_t, size_t, int) { calls.fetch_add(1); };
    schedule.run(pool, counting);
    EXPECT_EQ(calls.load(), static_cast<int>(kItems)) << threads << " threads";
  }
}
