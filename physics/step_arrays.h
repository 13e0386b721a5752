// The step's large arrays (manifolds, contact definitions, rows, lane groups) are sized anew
// every step and every element rewritten. Grown as std::vector grows them, a scene whose contacts
// increase by a few in its first steps (a pyramid settling: 40000 to 41200 points on the 100-level
// one) reallocates each to twice its size in the middle of a step: every old element copied and
// every new page faulted in, 20-30 ms a stage on that pyramid (docs/benchmarks.md, "The large
// arrays' growth"). resizeRewritten takes a quarter more than asked the first time and does not
// copy what the step will overwrite.
#pragma once

#include <cstddef>
#include <vector>

namespace substep {

// v resized to n, for a caller that writes every element before reading it: within the capacity a
// plain resize; beyond it, the old elements dropped and room taken for n and a quarter more, or
// for twice the old capacity if that is more (an array that keeps growing, a pile falling into
// place, grows as often as std::vector would, not once every quarter).
template <class T>
void resizeRewritten(std::vector<T>& v, size_t n) {
  if (n > v.capacity()) {
    const size_t room = n + n / 4 > 2 * v.capacity() ? n + n / 4 : 2 * v.capacity();
    v.clear();
    v.reserve(room);
  }
  v.resize(n);
}

}  // namespace substep
