#include "physics/parallel.h"

#include <algorithm>
#include <system_error>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace substep {

void spinPause() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#else
  std::this_thread::yield();
#endif
}

namespace {

// A worker spins this many rounds (about 50 µs) waiting for the next job before it sleeps: a
// step hands out jobs microseconds apart (a colour of the soft step's contacts is one), and
// waking a sleeping thread costs tens of microseconds.
constexpr int kSpinRounds = 2000;

uint64_t generation(uint64_t s) { return s >> 32; }

}  // namespace

// More threads than the machine runs at once only wait for each other (a scene or a recording
// may ask for 256): at most twice the cores, so that tests of uneven splits still run on a small
// machine. The trajectory does not depend on the number.
static int machineCores() { return static_cast<int>(std::max(1u, std::thread::hardware_concurrency())); }
static int usableThreads(int asked) { return std::max(1, std::min(asked, 2 * machineCores())); }

std::atomic<bool> WorkerPool::lastFirst_{false};

WorkerPool& WorkerPool::callerOnly() {
  static WorkerPool alone(1);
  return alone;
}

WorkerPool::WorkerPool(int threads) : threads_(usableThreads(threads)) {
  mayStayAwake_ = threads_ <= machineCores();  // read by the workers, which start below
  shares_.reset(new Share[static_cast<size_t>(threads_)]);
  try {
    for (int t = 1; t < threads_; ++t) workers_.emplace_back([this, t] { work(t); });
  } catch (const std::system_error&) {
    // The system gave fewer threads than asked: go on with those it gave.
    threads_ = static_cast<int>(workers_.size()) + 1;
  }
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lk(m_);
    stop_.store(true);
    state_.fetch_add(1ull << 32);  // a new generation wakes everyone to see stop_
  }
  cv_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void WorkerPool::doBlocks(int thread) {
  for (int k = 0; k < threads_; ++k) {
    Share& share = shares_[static_cast<size_t>((thread + k) % threads_)];
    for (size_t b; (b = share.next.fetch_add(1, std::memory_order_relaxed)) < share.end;) {
      try {
        fn_(ctx_, b, thread);
      } catch (...) {
        std::lock_guard<std::mutex> lk(errorM_);
        if (!error_) error_ = std::current_exception();
      }
    }
  }
}

void WorkerPool::run(size_t blocks, Fn fn, void* ctx) {
  // No worker is inside a job here (the last one was closed and every joiner left), so the job's
  // fields can be written; the release store of the new generation publishes them.
  fn_ = fn;
  ctx_ = ctx;
  const size_t t = static_cast<size_t>(threads_);
  for (size_t k = 0; k < t; ++k) {
    shares_[k].next.store(blocks * k / t, std::memory_order_relaxed);
    shares_[k].end = blocks * (k + 1) / t;
  }
  left_.store(0, std::memory_order_relaxed);
  const uint64_t gen = generation(state_.load(std::memory_order_relaxed)) + 1;
  state_.store(gen << 32, std::memory_order_seq_cst);
  if (sleepers_.load(std::memory_order_seq_cst) > 0) {
    { std::lock_guard<std::mutex> lk(m_); }
    cv_.notify_all();
  }
  doBlocks(0);
  // Close the job: a worker that has not joined yet never will (the caller did its blocks), and
  // those that joined are waited for.
  const uint64_t s = state_.fetch_or(kClosed, std::memory_order_acq_rel);
  const int joined = static_cast<int>(s & kCount);
  spinUntil([&] { return left_.load(std::memory_order_acquire) >= joined; }, kSpinRounds);
  if (error_) {
    std::exception_ptr e;
    std::swap(e, error_);
    std::rethrow_exception(e);
  }
}

void WorkerPool::work(int thread) {
  uint64_t seen = 0;
  for (;;) {
    uint64_t s = state_.load(std::memory_order_acquire);
    for (int spin = 0; generation(s) == seen; ++spin) {
      if (spin < kSpinRounds) {
        spinPause();
        s = state_.load(std::memory_order_acquire);
        continue;
      }
      if (mayStayAwake_ && busy_.load(std::memory_order_relaxed) > 0) {  // a Busy: no sleep
        spin = kSpinRounds;  // held there, however long the Busy lasts (no overflow)
        std::this_thread::yield();
        s = state_.load(std::memory_order_acquire);
        continue;
      }
      std::unique_lock<std::mutex> lk(m_);
      sleepers_.fetch_add(1, std::memory_order_seq_cst);
      cv_.wait(lk, [&] { return generation(state_.load(std::memory_order_seq_cst)) != seen; });
      sleepers_.fetch_sub(1, std::memory_order_relaxed);
      s = state_.load(std::memory_order_acquire);
      spin = 0;
    }
    if (stop_.load()) return;
    seen = generation(s);
    // Join the job unless it was closed (or replaced) meanwhile.
    bool joined = false;
    while (!(s & kClosed) && generation(s) == seen) {
      if (state_.compare_exchange_weak(s, s + 1, std::memory_order_acq_rel)) {
        joined = true;
        break;
      }
    }
    if (!joined) continue;
    doBlocks(thread);
    left_.fetch_add(1, std::memory_order_release);
  }
}

}  // namespace substep
