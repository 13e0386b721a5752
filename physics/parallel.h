// The threads a step runs on (SolverSettings::threads): the calling thread and threads - 1
// workers. Work is handed out in blocks as threads ask for them, so which thread does which block
// varies from run to run; every caller makes its result independent of that (each block writes
// only its own outputs, or in an OrderedSchedule what it shares in the order its waits set; what
// is combined is combined in block order afterwards), which is why a
// trajectory is the same to the last bit for any number of threads (docs/benchmarks.md,
// "Threads").
#pragma once

#include <algorithm>
#include <atomic>
#include <cassert>
#include <memory>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

namespace substep {

// Bodies a block takes in per-body work on a step's threads (each block writes only its bodies'
// entries): enough that handing a block out costs little beside it, few enough that 3000 bodies
// give both threads work.
constexpr size_t kBodyBlock = 1024;

// One round of a spin-wait: x86's PAUSE (the core's other thread runs meanwhile), elsewhere a yield.
void spinPause();
// Waits until done(): `spins` rounds of spinPause, then yielding the core (on more threads than
// cores, the thread waited for may need it).
template <class F>
void spinUntil(F done, int spins) {
  for (int spin = 0; !done(); ++spin)
    if (spin < spins) spinPause();
    else std::this_thread::yield();
}
// Pause rounds (a few µs) a sweep's thread waits for another's part before yielding.
constexpr int kSweepWaitSpins = 256;

// Each thread's running maximum (a sweep's largest change), a cache line each: threads writing
// neighbouring slots would share one. The largest of them does not depend on which thread
// noted what.
class ThreadMaxima {
 public:
  void reset(int threads) { slots_.assign(static_cast<size_t>(threads), Slot{}); }
  double& of(int thread) { return slots_[static_cast<size_t>(thread)].value; }
  double largest() const {
    double m = 0;
    for (const Slot& s : slots_) m = std::max(m, s.value);
    return m;
  }

 private:
  struct alignas(64) Slot {
    double value = 0;
  };
  std::vector<Slot> slots_;
};

class WorkerPool {
 public:
  // threads >= 1; 1 runs everything on the caller. Holds at most twice the machine's cores, and
  // fewer if the system gives fewer: threads() says how many.
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return threads_; }

  // A pool of the caller alone, for code given no pool (a hand-built context, a test): shared by
  // every thread, since it never hands anything out.
  static WorkerPool& callerOnly();

  // For tests, process-wide: the caller alone takes a job's blocks last first. Threads take blocks
  // as they ask for them, in any order, so a step must come out the same to the last bit; a block
  // that reads what another block of its job writes does not (tests/test_threads.cpp).
  static void takeBlocksLastFirst(bool on) { lastFirst_.store(on, std::memory_order_relaxed); }

  // f(block, thread) for every block in [0, blocks); thread in [0, threads()), 0 the caller.
  // Returns when all are done; rethrows the first exception a block threw.
  template <class F>
  void forBlocks(size_t blocks, F&& f) {
    if (threads_ == 1 || blocks <= 1) {
      if (lastFirst_.load(std::memory_order_relaxed))
        for (size_t b = blocks; b-- > 0;) f(b, 0);
      else
        for (size_t b = 0; b < blocks; ++b) f(b, 0);
      return;
    }
    using Callable = std::remove_reference_t<F>;
    run(blocks, [](void* ctx, size_t b, int t) { (*static_cast<Callable*>(ctx))(b, t); }, &f);
  }

  // While one lives (World::step holds one), the workers wait for the next job awake, spinning and
  // then yielding, never asleep: a step's serial parts between jobs (the colouring, the broadphase
  // tree) outlast a worker's spin, and waking a sleeping thread on this project's virtual machine
  // took 10-100 µs, at times milliseconds (docs/benchmarks.md, "Workers kept awake through a
  // step"). A pool with more threads than cores sleeps as before: there a waiting worker would
  // take a core from one with work.
  class Busy {
   public:
    explicit Busy(WorkerPool& pool) : pool_(pool) { pool_.busy_.fetch_add(1, std::memory_order_relaxed); }
    ~Busy() { pool_.busy_.fetch_sub(1, std::memory_order_relaxed); }
    Busy(const Busy&) = delete;
    Busy& operator=(const Busy&) = delete;

   private:
    WorkerPool& pool_;
  };

  // Workers asleep, waiting for a job (for tests).
  int sleeping() const { return sleepers_.load(std::memory_order_seq_cst); }

  // f(begin, end, thread) over [0, count) in ranges of `grain` items.
  template <class F>
  void forRange(size_t count, size_t grain, F&& f) {
    if (grain == 0) grain = 1;
    const size_t blocks = (count + grain - 1) / grain;
    forBlocks(blocks, [&](size_t b, int t) { f(b * grain, std::min(count, (b + 1) * grain), t); });
  }

 private:
  using Fn = void (*)(void*, size_t, int);
  void run(size_t blocks, Fn fn, void* ctx);
  void work(int thread);
  void doBlocks(int thread);

  // state_: the job's generation (high 32 bits), closed (bit 31: no thread may join it any more)
  // and the workers that joined it (low bits).
  static constexpr uint64_t kClosed = 1ull << 31;
  static constexpr uint64_t kCount = kClosed - 1;
  // The job's hot words on cache lines of their own: every block a thread takes is a fetch_add on
  // a share's next, which would otherwise evict the line that waiting workers poll state_ (and
  // read the job) from.
  alignas(64) std::atomic<uint64_t> state_{0};
  Fn fn_ = nullptr;  // the job: read by the workers that joined it
  void* ctx_ = nullptr;
  // The job's blocks in one contiguous share a thread, from the front; a thread done with its own
  // takes what is left of the others'. The same thread then tends to get the same bodies and
  // manifolds in every stage and step, and finds them in its own core's cache (docs/benchmarks.md,
  // "Threads").
  struct alignas(64) Share {
    std::atomic<size_t> next{0};
    size_t end = 0;
  };
  std::unique_ptr<Share[]> shares_;  // one a thread
  alignas(64) std::atomic<int> left_{0};
  alignas(64) std::atomic<int> sleepers_{0};
  alignas(64) std::atomic<int> busy_{0};  // Busy objects alive
  bool mayStayAwake_ = true;              // no more threads than cores
  std::atomic<bool> stop_{false};
  std::mutex m_;
  std::condition_variable cv_;
  std::exception_ptr error_;
  std::mutex errorM_;
  static std::atomic<bool> lastFirst_;
  int threads_;
  std::vector<std::thread> workers_;
};

// Items (groups of rows) solved in their order on every thread of a pool: a pass over them is one
// job in which each item is solved once the items before it on its moving bodies (its
// predecessors) are done in this pass. Every body's items are then solved in the serial order:
// the same numbers on any number of threads. An item waits only for the few it follows (a
// pyramid's runs overlap: a run's first groups can go while the run before ends), not for a whole
// run and a barrier. Each thread has its own list of the items, in order, and takes the next of it
// once that is ready; else the next of another list that is, so that one thread does all when the
// others are busy or off the core. Only a ready item is taken, and the first item not done is
// always the next of its list and ready: no wait lasts for ever. A5's and the soft step's lane
// groups.
class OrderedSchedule {
 public:
  // The predecessors of each of `items` items over `bodies` bodies: movingBodies(item, follow)
  // calls follow(body) for each body the item writes (one that moves). runOf(item) gives the
  // first and one past the last item of its run (items next to each other that share no moving
  // body). Each item goes on the list of one of `threads` threads, so that a body's velocities
  // mostly stay in one core's cache: the run cut into `threads` equal parts, the list of the part
  // its middle falls in; on a cut, of the two threads the one that last wrote most of its bodies.
  // A pyramid's runs are diagonals across it from the ground up, so a thread keeps its stretch
  // of them, the lower or the upper (docs/benchmarks.md, "The soft step's runs on two threads").
  template <class MovingBodies, class RunOf>
  void build(size_t items, size_t bodies, int threads, MovingBodies movingBodies, RunOf runOf) {
    last_.assign(bodies, -1);
    owner_.assign(bodies, -1);
    start_.assign(1, 0);
    before_.clear();
    const size_t t = static_cast<size_t>(std::max(1, threads));
    mine_.assign(t, {});
    if (next_.size() != t) next_ = std::vector<Cursor>(t);
    for (size_t item = 0; item < items; ++item) {
      const size_t first = before_.size();
      touched_.clear();
      movingBodies(item, [&](int body) {
        int& last = last_[static_cast<size_t>(body)];
        if (last == static_cast<int>(item)) return;  // named twice: once is enough (no wait on itself)
        if (last >= 0 && std::find(before_.begin() + static_cast<ptrdiff_t>(first), before_.end(), last) == before_.end())
          before_.push_back(last);
        last = static_cast<int>(item);
        touched_.push_back(body);
      });
      start_.push_back(static_cast<int>(before_.size()));
      const std::pair<size_t, size_t> run = runOf(item);
      assert(run.first <= item && item < run.second);
      const size_t middle = (2 * (item - run.first) + 1) * t, twice = 2 * (run.second - run.first);
      size_t thread = middle / twice;
      if (middle % twice == 0) {  // on the cut between thread - 1 and thread
        int votes = 0;  // for thread, against thread - 1
        for (int body : touched_) {
          const int o = owner_[static_cast<size_t>(body)];
          votes += o == static_cast<int>(thread) ? 1 : o == static_cast<int>(thread) - 1 ? -1 : 0;
        }
        if (votes <= 0) --thread;
      }
      for (int body : touched_) owner_[static_cast<size_t>(body)] = static_cast<int>(thread);
      mine_[thread].push_back(static_cast<int>(item));
    }
    if (done_.size() < items) {
      done_ = std::vector<std::atomic<uint32_t>>(items);
      epoch_ = 0;
    }
  }
  // f(item, item + 1, thread) for every item of the last build(), on every thread of the pool.
  template <class F>
  void run(WorkerPool& pool, F& f) {
    const uint32_t epoch = ++epoch_;
    if (epoch == 0) {  // wrapped: no flag may hold the new pass's number already
      for (std::atomic<uint32_t>& d : done_) d.store(0, std::memory_order_relaxed);
      epoch_ = 1;
      run(pool, f);
      return;
    }
    for (Cursor& c : next_) c.at.store(0, std::memory_order_relaxed);
    failed_.store(false, std::memory_order_relaxed);
    pool.forBlocks(mine_.size(), [&](size_t own, int thread) {
      // The next item of its own list once it is ready, else the next of another list that is (its
      // thread is busy, or off the core: a loaded machine), else wait. Only ready items are taken,
      // so whoever takes one solves it at once.
      for (int idle = 0;;) {
        bool left = false, took = false;
        for (size_t k = 0; k < mine_.size() && !took; ++k) {
          const size_t list = (own + k) % mine_.size();
          std::atomic<size_t>& next = next_[list].at;
          size_t at = next.load(std::memory_order_acquire);
          if (at >= mine_[list].size()) continue;
          left = true;
          const size_t g = static_cast<size_t>(mine_[list][at]);
          if (!ready(g, epoch)) continue;
          took = true;  // or another thread did: look again at once
          if (!next.compare_exchange_strong(at, at + 1, std::memory_order_acq_rel)) break;
          try {
            f(g, g + 1, thread);
          } catch (...) {  // the items after it would wait for ever: all stop, the pool rethrows
            failed_.store(true, std::memory_order_relaxed);
            throw;
          }
          done_[g].store(epoch, std::memory_order_release);
        }
        if (!left || failed_.load(std::memory_order_relaxed)) return;
        if (took) idle = 0;
        else if (++idle < kSweepWaitSpins) spinPause();
        else std::this_thread::yield();
      }
    });
  }

 private:
  std::vector<int> start_, before_;  // item g's predecessors: before_[start_[g] .. start_[g + 1])
  std::vector<int> last_;            // scratch: each body's last item
  std::vector<int> owner_, touched_;  // scratch: each body's last thread; an item's moving bodies
  std::vector<std::vector<int>> mine_;  // each thread's items, in order
  std::vector<std::atomic<uint32_t>> done_;  // the pass each item was last solved in
  uint32_t epoch_ = 0;
  struct alignas(64) Cursor {  // a list's next item, on a line of its own
    std::atomic<size_t> at{0};
  };
  std::vector<Cursor> next_;  // one a list
  std::atomic<bool> failed_{false};  // an item threw in this pass

  bool ready(size_t g, uint32_t epoch) const {
    for (int p = start_[g]; p < start_[g + 1]; ++p)
      if (done_[static_cast<size_t>(before_[static_cast<size_t>(p)])].load(std::memory_order_acquire) != epoch) return false;
    return true;
  }
};

}  // namespace substep
