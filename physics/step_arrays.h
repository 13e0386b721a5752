// The step's large arrays (manifolds, contact definitions, rows, lane groups) are sized anew
// every step and every element rewritten. Grown as std::vector grows them, a scene whose contacts
// increase by a few in its first steps (a pyramid settling: 40000 to 41200 points on the 100-level
// one) reallocates each to twice its size in the middle of a step: every old element copied and
// every new page faulted in, 20-30 ms a stage on that pyramid (docs/benchmarks.md, "The large
// arrays' growth"). resizeRewritten takes a quarter more than asked the first time and does not
// copy what the step will overwrite.
#pragma once

#include "physics/parallel.h"

#include <cstddef>
#include <vector>

namespace substep {

// The pages of [p, p + bytes) written once each, shared out on the pool's threads. Taking new
// storage for a step's array, the thread that constructs its elements would otherwise take every
// page fault alone (11-15 µs a fault on this kind of virtual machine: the 100-level pyramid's
// contact definitions, 2400 pages, were most of its first step's 32 ms of s2); faults on two
// threads take 0.6 of the time (docs/benchmarks.md, "First steps on the threads"). Below
// kTouchedBytes it is not worth a job.
constexpr size_t kTouchedBytes = 256 * 1024;
inline void touchPages(void* p, size_t bytes, WorkerPool& pool) {
  if (bytes < kTouchedBytes || pool.threads() == 1) return;
  constexpr size_t kPage = 4096, kPagesABlock = 64;
  volatile char* base = static_cast<char*>(p);
  const size_t pages = (bytes + kPage - 1) / kPage;
  pool.forRange(pages, kPagesABlock, [&](size_t first, size_t last, int) {
    for (size_t i = first; i < last; ++i) base[i * kPage] = 0;
  });
  base[bytes - 1] = 0;  // the last page, when p is not at a page's start
}

// v resized to n, for a caller that writes every element before reading it: within the capacity a
// plain resize; beyond it, the old elements dropped and room taken for n and a quarter more, or
// for twice the old capacity if that is more (an array that keeps growing, a pile falling into
// place, grows as often as std::vector would, not once every quarter), its pages first touched on
// the pool's threads.
template <class T>
void resizeRewritten(std::vector<T>& v, size_t n, WorkerPool& pool = WorkerPool::callerOnly()) {
  if (n > v.capacity()) {
    const size_t room = n + n / 4 > 2 * v.capacity() ? n + n / 4 : 2 * v.capacity();
    v.clear();
    v.reserve(room);
    touchPages(v.data(), room * sizeof(T), pool);
  }
  v.resize(n);
}

}  // namespace substep
