#include "render/ahead.h"

#include <algorithm>
#include <chrono>

namespace substep::render {

SessionAhead::SessionAhead(RenderSession& session, std::vector<double> times, int depth)
    : session_(session), times_(std::move(times)), depth_(static_cast<size_t>(std::max(depth, 1))),
      thread_([this] { run(); }) {}

SessionAhead::~SessionAhead() { stop(); }

void SessionAhead::stop() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void SessionAhead::run() {
  try {
    for (double t : times_) {
      {
        std::unique_lock<std::mutex> lock(mu_);
        cv_.wait(lock, [this] { return stop_ || ready_.size() < depth_; });
        if (stop_) break;
      }
      session_.advanceTo(t);
      Frame f;
      f.diverged = session_.firstDiverged() != nullptr;
      if (!f.diverged) f.lists = session_.drawLists();
      const bool last = f.diverged;
      {
        std::lock_guard<std::mutex> lock(mu_);
        ready_.push_back(std::move(f));
      }
      cv_.notify_all();
      if (last) break;
    }
  } catch (...) {
    std::lock_guard<std::mutex> lock(mu_);
    error_ = std::current_exception();
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    done_ = true;
  }
  cv_.notify_all();
}

SessionAhead::Frame SessionAhead::next() {
  const auto t0 = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait(lock, [this] { return !ready_.empty() || done_ || error_; });
  waited_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (ready_.empty()) {
    if (error_) std::rethrow_exception(error_);
    return {};
  }
  Frame f = std::move(ready_.front());
  ready_.pop_front();
  lock.unlock();
  cv_.notify_all();
  return f;
}

}  // namespace substep::render
