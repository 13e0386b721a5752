// How long two cores take to hand a cache line to each other and back (substep-bench
// --core-check): two threads, each pinned to its core, pass one atomic back and forth. On this
// project's virtual machine the host puts the two vCPUs on cores that share a cache (75-106 ns a
// round trip) or on two dies (335-349 ns), for minutes at a time; a step whose threads hand work
// to each other unit by unit (A5's large islands) gains little in the second placement, so a
// two-thread figure is read with the placement it ran in (docs/benchmarks.md, "Two threads on
// this machine: two placements").
#pragma once

#include "app/bench/bench_stats.h"

#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>
#include <vector>

namespace substep::bench {

// The median over `batches` of the mean round trip [ns] of `rounds` hand-overs between cores a
// and b; NaN if a == b or either thread cannot be pinned. The calling thread keeps its cores.
inline double cacheLineRoundTrip(int a, int b, int rounds = 2000, int batches = 9) {
  if (a == b || rounds < 1 || batches < 1) return NAN;
  const auto pinTo = [](int core) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(core, &set);
    return pthread_setaffinity_np(pthread_self(), sizeof set, &set) == 0;
  };
  cpu_set_t before;
  if (pthread_getaffinity_np(pthread_self(), sizeof before, &before) != 0) return NAN;
  struct alignas(64) Line {
    std::atomic<long> turn{0};  // odd: the other thread's move; even: ours
  };
  Line line;
  alignas(64) std::atomic<int> ready{0};  // the other thread: 1 pinned, -1 could not pin
  alignas(64) std::atomic<bool> stop{false};
  const long total = static_cast<long>(rounds) * batches;
  std::thread other([&] {
    if (!pinTo(b)) {
      ready.store(-1);
      return;
    }
    ready.store(1);
    for (long i = 0; i < total; ++i) {
      while (line.turn.load(std::memory_order_acquire) != 2 * i + 1)
        if (stop.load(std::memory_order_relaxed)) return;
      line.turn.store(2 * i + 2, std::memory_order_release);
    }
  });
  while (ready.load() == 0) std::this_thread::yield();
  std::vector<double> batch;
  if (ready.load() == 1 && pinTo(a)) {
    for (int k = 0; k < batches; ++k) {
      const auto start = std::chrono::steady_clock::now();
      for (long i = static_cast<long>(k) * rounds; i < static_cast<long>(k + 1) * rounds; ++i) {
        line.turn.store(2 * i + 1, std::memory_order_release);
        while (line.turn.load(std::memory_order_acquire) != 2 * i + 2) {
        }
      }
      batch.push_back(std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count() /
                      rounds);
    }
  }
  stop.store(true);
  other.join();
  pthread_setaffinity_np(pthread_self(), sizeof before, &before);
  return app::median(batch);  // NaN without a batch
}

}  // namespace substep::bench
