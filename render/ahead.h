// A render session stepped on a thread of its own, ahead of the drawing: while frame k is drawn,
// the physics of the frames after it runs and their draw lists are made (up to `depth` frames
// ahead). On two cores the physics then costs the video no time of its own when the drawing
// leaves a core free (llvmpipe's threads wait for the main thread between passes).
//
// The session belongs to the thread from construction until stop() (or destruction): read it
// (its panels' costs, a diverged panel) only after that.
#pragma once

#include "render/session.h"

#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace substep::render {

class SessionAhead {
 public:
  // Frame k shows the session advanced to times[k] (advanceTo: forward only).
  SessionAhead(RenderSession& session, std::vector<double> times, int depth = 2);
  ~SessionAhead();  // stop()
  SessionAhead(const SessionAhead&) = delete;
  SessionAhead& operator=(const SessionAhead&) = delete;

  struct Frame {
    std::vector<DrawList> lists;  // one per panel, as RenderSession::drawLists()
    bool diverged = false;        // a panel diverged on the way: no lists, and no frames after it
  };
  // The next frame, in order; waits for the physics if it is behind. Rethrows what the stepping
  // threw. Past the last frame (or a divergence): a frame with no lists.
  Frame next();
  void stop();  // ends the thread (the frame being stepped is finished first); the session is the caller's again
  double waitedSeconds() const { return waited_; }  // time next() spent waiting for the physics

 private:
  void run();

  RenderSession& session_;
  const std::vector<double> times_;
  const size_t depth_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Frame> ready_;
  bool stop_ = false, done_ = false;
  std::exception_ptr error_;
  double waited_ = 0;
  std::thread thread_;  // last: started once everything above exists
};

}  // namespace substep::render
