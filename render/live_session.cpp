#include "render/live_session.h"

#include "physics/failure.h"
#include "render/frame_sink.h"
#include "render/scene_builder.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <stdexcept>

namespace substep::render {

namespace {

double wallNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

constexpr double kWindow = 1.0;  // [s] the rates of the stats are measured over
constexpr int kMaxClips = 8;     // kept per session; the oldest finished one goes first
constexpr int kMaxClipsAtOnce = 2;
constexpr double kMaxOwed = 0.25;  // [s] of wall time a tick may make up for
// Why play stopped at an end of the timeline (not a divergence): cleared when play starts again.
constexpr const char* kAtFirstKept = "at the first kept step";
constexpr const char* kEndOfRecording = "the end of the recording";
// The sizes a session draws at, as shares of its own (adaptSize): each about half the pixels of
// the one before. Smaller than half, the HUD's text would crowd the frame.
constexpr double kSizeSteps[] = {1.0, 0.75, 0.5};
constexpr int kSizeStepCount = sizeof kSizeSteps / sizeof kSizeSteps[0];
constexpr int kMinFramesToAdapt = 5;  // drawn in a window for its draw time to decide a size

struct Size {
  int width, height;
  std::string text() const { return std::to_string(width) + "x" + std::to_string(height); }
};

// The frames' size at a step of kSizeSteps: each side its share, even (the clips' yuv420p).
Size sizeAtStep(const LiveConfig& c, int step) {
  auto even = [](int n, double share) { return std::max(2, 2 * static_cast<int>(std::lround(0.5 * n * share))); };
  return {even(c.width, kSizeSteps[step]), even(c.height, kSizeSteps[step])};
}

}  // namespace

FairGate::Turn::Turn(FairGate* g) : g_(g) {
  if (!g_) return;
  std::unique_lock<std::mutex> lk(g_->m_);
  const unsigned long long ticket = g_->next_++;
  g_->cv_.wait(lk, [&] { return ticket == g_->head_ && g_->busy_ < g_->slots_; });
  ++g_->head_;
  ++g_->busy_;
  lk.unlock();
  g_->cv_.notify_all();  // the next ticket may go too when there is another slot
}

int FairGate::waiting() const {
  std::lock_guard<std::mutex> lk(m_);
  return static_cast<int>(next_ - head_);
}

FairGate::Turn::~Turn() {
  if (!g_) return;
  {
    std::lock_guard<std::mutex> lk(g_->m_);
    --g_->busy_;
  }
  g_->cv_.notify_all();
}

LiveSession::LiveSession(std::shared_ptr<const Scene> scene, const std::vector<PanelSetup>& panels, const Look& look,
                         const LiveConfig& config)
    : config_(config), session_(std::move(scene), panels, look), look_(look) {
  config_.fps = std::max(1, config_.fps);
  session_.setHistoryLimits(config_.timeline);
  lastTouch_ = wallNow();
  collectStats(stats_);  // stats from the start, before the first tick
  stats_.width = config_.width;
  stats_.height = config_.height;
  thread_ = std::thread([this] { run(); });
  encoder_ = std::thread([this] { encodeLoop(); });
}

LiveSession::~LiveSession() { close(); }

void LiveSession::close() {
  if (closed_.exchange(true)) return;
  {
    std::lock_guard<std::mutex> lk(stopM_);
    stop_ = true;
  }
  stopCv_.notify_all();
  {
    std::lock_guard<std::mutex> lk(frameM_);
  }
  frameCv_.notify_all();
  {
    std::lock_guard<std::mutex> lk(encM_);
  }
  encCv_.notify_all();
  if (thread_.joinable()) thread_.join();
  if (encoder_.joinable()) encoder_.join();
  // Clips being encoded finish (ffmpeg is quick); their threads take clipM_ at the end.
  std::vector<std::thread*> encoders;
  {
    std::lock_guard<std::mutex> lk(clipM_);
    for (auto& [id, c] : clips_)
      if (c->encoder.joinable()) encoders.push_back(&c->encoder);
  }
  for (std::thread* t : encoders) t->join();
}

void LiveSession::touch() { lastTouch_ = wallNow(); }

double LiveSession::idleSeconds() const { return viewers_ > 0 ? 0.0 : std::max(0.0, wallNow() - lastTouch_); }

void LiveSession::play(double speed) {
  std::lock_guard<std::mutex> lk(m_);
  if (!playing_ || (speed < 0) != (speed_ < 0)) goal_ = session_.time();
  if (status_ == kAtFirstKept || status_ == kEndOfRecording) status_.clear();
  if (session_.recorded() && speed > 0 && session_.ended()) session_.view(session_.firstKept());  // again from its start
  playing_ = true;
  speed_ = speed;
  seekTo_.reset();
  dirty_ = true;
  republish();
}

void LiveSession::pause() {
  std::lock_guard<std::mutex> lk(m_);
  playing_ = false;
  seekTo_.reset();
  dirty_ = true;
  republish();
}

bool LiveSession::playing() const {
  std::lock_guard<std::mutex> lk(m_);
  return playing_;
}

double LiveSession::step(int count) {
  std::lock_guard<std::mutex> lk(m_);
  playing_ = false;
  seekTo_.reset();
  if (count < 0) session_.viewBy(count);
  for (int k = 0; k < count && !session_.firstDiverged() && !session_.ended(); ++k) session_.step();
  if (const Panel* p = session_.firstDiverged(); p && !reportedDivergence_) {
    status_ = p->problem();
    reportedDivergence_ = true;
  }
  dirty_ = true;
  republish();
  return session_.time();
}

void LiveSession::reset() {
  std::lock_guard<std::mutex> lk(m_);
  if (session_.recorded()) {
    session_.view(session_.firstKept());
    seekTo_.reset();
    goal_ = session_.time();
    status_.clear();
    dirty_ = true;
  } else {
    session_.reset();
    restarted();
  }
  republish();
}

void LiveSession::live() {
  std::lock_guard<std::mutex> lk(m_);
  session_.viewLive();
  playing_ = false;
  seekTo_.reset();
  dirty_ = true;
  republish();
}

void LiveSession::restarted() {
  seekTo_.reset();
  goal_ = 0;
  status_.clear();
  reportedDivergence_ = false;
  dirty_ = true;
}

void LiveSession::seek(double t) {
  std::lock_guard<std::mutex> lk(m_);
  const double dt = session_.panel(0).settings().dt;
  playing_ = false;
  seekTo_.reset();
  if (t + 0.5 * dt >= session_.firstKept() && (t - 0.5 * dt <= session_.lastKept() || session_.ended())) {
    session_.view(t);  // kept: shown at once
  } else if (t + 0.5 * dt < session_.firstKept()) {
    session_.reset();  // older than the kept past: from the start again
    status_.clear();
    reportedDivergence_ = false;
    seekTo_ = t;
  } else {
    session_.viewLive();  // later than the newest: step to it
    seekTo_ = t;
  }
  dirty_ = true;
  republish();
}

void LiveSession::republish() {
  LiveStats s;
  collectStats(s);
  s.seeking = seekTo_.has_value();
  {
    std::lock_guard<std::mutex> lk(frameM_);
    s.seq = stats_.seq + 1;
    s.frames = stats_.frames;
    s.fps = stats_.fps;
    s.achieved = s.playing ? stats_.achieved : 0;
    s.behind = s.playing && stats_.behind;
    s.physicsMs = stats_.physicsMs;
    s.drawMs = stats_.drawMs;
    s.encodeMs = stats_.encodeMs;
    s.jpegBytes = stats_.jpegBytes;
    s.width = stats_.width;
    s.height = stats_.height;
    s.sizeNote = stats_.sizeNote;
    stats_ = std::move(s);
  }
  frameCv_.notify_all();
}

// --- the session's thread --------------------------------------------------------------------

void LiveSession::run() {
  std::unique_ptr<GlRenderer> renderer;
  try {
    renderer = std::make_unique<GlRenderer>(config_.width, config_.height, config_.renderer);
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lk(m_);
    status_ = std::string("cannot draw: ") + e.what();
  }
  const double period = 1.0 / config_.fps;
  double next = wallNow();
  lastTick_ = windowStart_ = next;
  while (!stop_) {
    tick(renderer.get(), wallNow());
    const Size size = sizeAtStep(config_, sizeStep_);
    if (renderer && (renderer->width() != size.width || renderer->height() != size.height)) {
      try {
        renderer.reset();  // one context at a time on this thread
        renderer = std::make_unique<GlRenderer>(size.width, size.height, config_.renderer);
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> lk(m_);
        status_ = std::string("cannot draw at ") + size.text() + ": " + e.what();
      }
    }
    next += period;
    const double now = wallNow();
    if (next < now) next = now;  // late: the next tick now, no catching up on missed ones
    std::unique_lock<std::mutex> lk(stopM_);
    stopCv_.wait_for(lk, std::chrono::duration<double>(next - now), [&] { return stop_.load(); });
  }
  renderer.reset();  // its context is current on this thread
}

void LiveSession::advance(double now, double wallDt) {
  std::unique_lock<std::mutex> lk(m_);
  if (!playing_ && !seekTo_) return;
  // Seeking runs as fast as it can but still hands the thread back every tick, so that frames
  // show the progress and requests get the lock.
  const double budgetEnd = now + config_.physicsBudget / config_.fps;
  if (!seekTo_) {
    // A stall (a long step, a wait for the turn to draw) is not owed, but it is falling behind.
    goal_ += speed_ * std::min(wallDt, kMaxOwed);
    if (wallDt > kMaxOwed) behindTick_ = true;
  }
  if (playing_ && speed_ < 0) {  // backwards: through the kept steps only
    const double first = session_.firstKept();
    session_.view(std::max(goal_, first));
    dirty_ = true;
    if (goal_ <= first) {
      playing_ = false;
      status_ = kAtFirstKept;
    }
    return;
  }
  const double goal = seekTo_ ? *seekTo_ : goal_;
  for (;;) {
    double t = std::numeric_limits<double>::infinity(), dt = t;
    for (int i = 0; i < session_.panelCount(); ++i) {
      const Panel& p = session_.panel(i);
      if (p.ended()) continue;
      t = std::min(t, p.state().time);
      dt = std::min(dt, p.settings().dt);
    }
    if (!std::isfinite(t) || t + 0.5 * dt > goal) {  // there, or every panel ended
      if (seekTo_) {
        seekTo_.reset();
        playing_ = false;
      }
      if (!std::isfinite(t) && session_.recorded() && playing_) {
        playing_ = false;
        status_ = kEndOfRecording;
      }
      break;
    }
    if (wallNow() > budgetEnd) {
      if (!seekTo_) {
        goal_ = t;  // what could not be done is dropped
        behindTick_ = true;
      }
      break;
    }
    session_.advanceTo(t + dt);
    dirty_ = true;
    if (const Panel* p = session_.firstDiverged(); p && !reportedDivergence_) {
      status_ = p->problem();
      reportedDivergence_ = true;
      playing_ = false;
      seekTo_.reset();
      break;
    }
    lk.unlock();  // requests may change the session between steps
    std::this_thread::yield();
    lk.lock();
    if (!playing_ && !seekTo_) break;
  }
}

void LiveSession::collectStats(LiveStats& s) {
  s.playing = playing_;
  s.seeking = seekTo_.has_value();
  s.speed = speed_;
  s.status = status_;
  s.first = session_.firstKept();
  s.last = session_.lastKept();
  s.shown = session_.time();
  s.shownStep = session_.panel(0).state().step;
  s.live = session_.live();
  s.recorded = session_.recorded();
  const int n = session_.panelCount();
  prevSteps_.resize(static_cast<size_t>(n), 0);
  prevPhysics_.resize(static_cast<size_t>(n), 0);
  lastStepMs_.resize(static_cast<size_t>(n), std::numeric_limits<double>::quiet_NaN());
  for (int i = 0; i < n; ++i) {
    const Panel& p = session_.panel(i);
    const World& w = p.world();
    const StepReport& r = w.lastReport();
    LivePanelStats ps;
    ps.name = p.name();
    ps.settings = settingsLine(p.settings(), LineDetail::Hud);
    ps.time = p.state().time;
    ps.steps = p.steps();
    const size_t k = static_cast<size_t>(i);
    if (p.steps() < prevSteps_[k]) {  // replaced or reset
      prevSteps_[k] = 0;
      prevPhysics_[k] = 0;
    }
    if (p.steps() > prevSteps_[k])
      lastStepMs_[k] = 1e3 * (p.physicsSeconds() - prevPhysics_[k]) / static_cast<double>(p.steps() - prevSteps_[k]);
    prevSteps_[k] = p.steps();
    prevPhysics_[k] = p.physicsSeconds();
    ps.stepMs = lastStepMs_[k];
    ps.stages = r.times;
    ps.pairs = r.pairs;
    ps.diverged = p.diverged();
    ps.ended = p.ended();
    ps.problem = p.problem();
    // The measures of the step shown (a diverged panel's last finite one).
    const Snapshot& shown = p.shown();
    ps.contacts = static_cast<int>(shown.contacts.size());
    ps.manifolds = static_cast<int>(shown.manifolds.size());
    ps.penetration = shown.deepest();
    ps.jointError = shown.worstJointError();
    ps.kinetic = kineticEnergy(session_.scene().model, shown.state);
    ps.potential = potentialEnergy(session_.scene().model, shown.state);
    s.panels.push_back(std::move(ps));
  }
}

void LiveSession::tick(GlRenderer* renderer, double now) {
  const double wallDt = now - lastTick_;
  lastTick_ = now;
  behindTick_ = false;
  advance(now, wallDt);
  const double physicsEnd = wallNow();

  bool imageWanted;
  {
    std::lock_guard<std::mutex> lk(frameM_);
    imageWanted = imageWanted_;
  }
  const bool recording = recording_ > 0;
  std::vector<DrawList> lists;
  LiveStats s;
  double simTime;
  {
    std::lock_guard<std::mutex> lk(m_);
    // Drawn while someone looks and something changed; every tick while a clip records.
    if (renderer && (recording || ((viewers_ > 0 || imageWanted) && dirty_))) {
      lists = session_.drawLists();
      dirty_ = false;
    }
    collectStats(s);
    simTime = session_.time();
  }
  std::shared_ptr<Image> image;
  double drawEnd = physicsEnd, drawWait = 0;
  if (!lists.empty()) {
    try {
      image = spareImage();
      FairGate::Turn turn(config_.drawGate.get());
      const double d0 = wallNow();  // the draw's own time, not the wait for its turn
      renderer->render(gridViews(lists, renderer->width(), renderer->height()), *image);
      drawEnd = wallNow();
      drawWait = d0 - physicsEnd;
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lk(m_);
      status_ = std::string("cannot draw: ") + e.what();
      playing_ = false;
      image.reset();
    }
  }

  // Rates over the last second.
  const double simNow = simTime;
  if (simNow >= lastSimTime_) windowSim_ += simNow - lastSimTime_;
  lastSimTime_ = simNow;
  windowPhysics_ += physicsEnd - now;
  ++windowTicks_;
  windowBehind_ = windowBehind_ || behindTick_;
  if (image) {
    ++windowFrames_;
    windowDraw_ += drawEnd - physicsEnd - drawWait;
  }
  if (now - windowStart_ >= kWindow) {
    const double span = now - windowStart_;
    rateFps_ = windowFrames_ / span;
    rateAchieved_ = windowSim_ / span;
    ratePhysics_ = 1e3 * windowPhysics_ / windowTicks_;
    rateDraw_ = windowFrames_ ? 1e3 * windowDraw_ / windowFrames_ : 0;
    rateBehind_ = windowBehind_;
    if (config_.adaptSize && renderer) adaptSize(windowFrames_, rateDraw_);
    windowStart_ = now;
    windowSim_ = windowPhysics_ = windowDraw_ = 0;
    windowFrames_ = windowTicks_ = 0;
    windowBehind_ = false;
  }
  s.fps = rateFps_;
  s.achieved = s.playing ? rateAchieved_ : 0;
  // Behind: a tick fell short in the last second and the second as a whole did too (a tick
  // late now and then is not worth a warning).
  s.behind = s.playing && rateBehind_ && rateAchieved_ < 0.95 * s.speed;
  s.physicsMs = ratePhysics_;
  s.drawMs = rateDraw_;
  s.encodeMs = encodeMs_;
  s.width = renderer ? renderer->width() : config_.width;
  s.height = renderer ? renderer->height() : config_.height;
  s.sizeNote = sizeNote_;
  if (!image) {
    publish(nullptr, nullptr, s, simTime, now);
    return;
  }
  // To the encoder, which publishes it with its stats. One frame waits at most: when JPEG is the
  // slower half, the session thread waits here rather than drawing frames nobody gets.
  {
    std::unique_lock<std::mutex> lk(encM_);
    encCv_.wait(lk, [&] { return !drawn_ || stop_; });
    drawn_ = Drawn{std::move(image), s, simTime, now};
  }
  encCv_.notify_all();
}

void LiveSession::adaptSize(int framesDrawn, double drawMs) {
  if (framesDrawn < kMinFramesToAdapt) return;  // paused, nobody watching: no measure
  const double period = 1e3 / config_.fps;       // [ms]
  const double shareNow = kSizeSteps[sizeStep_];
  // Slow: the drawing alone takes the whole tick. Fast: the size above, its pixels costing as
  // these do (an overestimate: the geometry's cost does not grow with them), would leave a
  // quarter of the tick, so that the session does not go up only to come down again.
  const bool slow = drawMs > 0.95 * period && sizeStep_ + 1 < kSizeStepCount;
  const double shareUp = sizeStep_ > 0 ? kSizeSteps[sizeStep_ - 1] : shareNow;
  const bool fast = sizeStep_ > 0 && drawMs * (shareUp * shareUp) / (shareNow * shareNow) < 0.75 * period;
  slowWindows_ = slow ? slowWindows_ + 1 : 0;
  fastWindows_ = fast ? fastWindows_ + 1 : 0;
  const bool down = slowWindows_ >= 2;  // two seconds in a row: not a passing stall
  if (!down && fastWindows_ < 3) return;
  const Size before = sizeAtStep(config_, sizeStep_);
  sizeStep_ += down ? 1 : -1;
  slowWindows_ = fastWindows_ = 0;
  if (sizeStep_ == 0) {
    sizeNote_.clear();
    return;
  }
  char why[120];
  if (down)
    std::snprintf(why, sizeof why, "at %s a frame took %.0f ms, %.0f fps", before.text().c_str(), drawMs, 1e3 / drawMs);
  else
    std::snprintf(why, sizeof why, "the full size would take about %.0f ms a frame", drawMs / (shareNow * shareNow));
  sizeNote_ = "drawn at " + sizeAtStep(config_, sizeStep_).text() + " of " + sizeAtStep(config_, 0).text() + ": " + why +
              ", below the " + std::to_string(config_.fps) + " fps asked";
}

std::shared_ptr<Image> LiveSession::spareImage() {
  std::lock_guard<std::mutex> lk(encM_);
  if (spare_.empty()) return std::make_shared<Image>();
  std::shared_ptr<Image> img = std::move(spare_.back());
  spare_.pop_back();
  return img;
}

void LiveSession::encodeLoop() {
  for (;;) {
    Drawn d;
    {
      std::unique_lock<std::mutex> lk(encM_);
      encCv_.wait(lk, [&] { return drawn_ || stop_; });
      if (stop_) return;
      d = std::move(*drawn_);
      drawn_.reset();
    }
    encCv_.notify_all();
    std::shared_ptr<const std::string> jpeg;
    double t0 = 0;
    try {
      FairGate::Turn turn(config_.encodeGate.get());
      t0 = wallNow();
      jpeg = std::make_shared<const std::string>(encodeJpeg(*d.image, config_.jpegQuality));
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lk(m_);
      status_ = std::string("cannot encode: ") + e.what();
      continue;
    }
    const double ms = 1e3 * (wallNow() - t0);
    encodeMs_ = encodeMs_ > 0 ? 0.9 * encodeMs_ + 0.1 * ms : ms;  // smoothed over about ten frames
    d.stats.encodeMs = encodeMs_;
    publish(std::move(jpeg), std::move(d.image), d.stats, d.simTime, d.wall);
  }
}

void LiveSession::publish(std::shared_ptr<const std::string> jpeg, std::shared_ptr<Image> image, const LiveStats& s,
                          double simTime, double now) {
  {
    std::lock_guard<std::mutex> lk(frameM_);
    if (jpeg) {
      latest_.seq += 1;
      latest_.jpeg = jpeg;
      latest_.time = simTime;
      std::swap(front_, image);
      // The frame before is drawn into again, unless a request still holds it (never a torn image).
      if (image && image.use_count() == 1) {
        std::lock_guard<std::mutex> el(encM_);
        if (spare_.empty()) spare_.push_back(std::move(image));
      }
      history_.push_back({now, jpeg});
      while (!history_.empty() && history_.front().wall < now - config_.historySeconds) history_.pop_front();
      imageWanted_ = false;
      ++framesDrawn_;
    }
    const long long seq = stats_.seq + 1;
    stats_ = s;
    stats_.seq = seq;
    stats_.frames = framesDrawn_;
    stats_.jpegBytes = latest_.jpeg ? static_cast<int>(latest_.jpeg->size()) : 0;
  }
  frameCv_.notify_all();
  if (!jpeg || recording_ == 0) return;
  std::lock_guard<std::mutex> lk(clipM_);
  for (auto& [id, c] : clips_) {
    if (c->info.state != "recording") continue;
    c->jpegs.push_back(jpeg);
    c->info.frames = static_cast<int>(c->jpegs.size());
    if (c->info.frames >= c->wanted) {
      --recording_;
      startEncoding(*c);
    }
  }
}

// --- what requests read ----------------------------------------------------------------------

LiveFrame LiveSession::waitFrame(long long after, double timeout) {
  std::unique_lock<std::mutex> lk(frameM_);
  frameCv_.wait_for(lk, std::chrono::duration<double>(timeout), [&] { return closed_ || latest_.seq > after; });
  return closed_ ? LiveFrame{} : latest_;
}

std::shared_ptr<const Image> LiveSession::image(double timeout) {
  long long seq;
  {
    std::lock_guard<std::mutex> lk(frameM_);
    // While a viewer watches, the front frame is at most a tick old.
    if (front_ && viewers_ > 0) return front_;
    seq = latest_.seq;
  }
  bool changed;
  {
    std::lock_guard<std::mutex> lk(m_);
    changed = dirty_;
  }
  std::unique_lock<std::mutex> lk(frameM_);
  if (!changed && front_) return front_;  // nothing changed since it was drawn
  imageWanted_ = true;
  frameCv_.wait_for(lk, std::chrono::duration<double>(timeout), [&] { return closed_ || latest_.seq > seq; });
  return latest_.seq > seq || (!changed && front_) ? front_ : nullptr;
}

LiveStats LiveSession::waitStats(long long after, double timeout) const {
  std::unique_lock<std::mutex> lk(frameM_);
  frameCv_.wait_for(lk, std::chrono::duration<double>(timeout), [&] { return closed_ || stats_.seq > after; });
  return stats_;
}

LiveStats LiveSession::stats() const {
  std::lock_guard<std::mutex> lk(frameM_);
  return stats_;
}

// --- clips -----------------------------------------------------------------------------------

int LiveSession::record(const std::string& mode, double seconds) {
  if (config_.ffmpeg.empty())
    throw std::invalid_argument("clips need the ffmpeg program, which the server did not find (Debian: apt-get install ffmpeg)");
  if (mode != "last" && mode != "next") throw std::invalid_argument("mode: expected last or next, got \"" + mode + "\"");
  auto c = std::make_unique<Clip>();
  c->info.mode = mode;
  c->info.seconds = seconds;
  if (mode == "last") {
    std::lock_guard<std::mutex> lk(frameM_);
    const double from = wallNow() - seconds;
    for (const Stored& f : history_)
      if (f.wall >= from) c->jpegs.push_back(f.jpeg);
    if (c->jpegs.empty())
      throw std::invalid_argument("no frames were drawn in the last " + numberText(seconds) +
                                  " s: frames are drawn while the stream is watched");
  } else {
    c->wanted = std::max(1, static_cast<int>(std::lround(seconds * config_.fps)));
  }
  std::lock_guard<std::mutex> lk(clipM_);
  if (closed_) throw std::invalid_argument("the session is closed");
  int busy = 0;
  for (const auto& [id, old] : clips_) busy += old->info.state == "recording" || old->info.state == "encoding";
  if (busy >= kMaxClipsAtOnce)
    throw std::invalid_argument("already making " + std::to_string(busy) + " clips; wait for one to finish");
  // Room for it: the oldest finished clip goes (its file with it).
  while (static_cast<int>(clips_.size()) >= kMaxClips) {
    auto it = std::find_if(clips_.begin(), clips_.end(), [](const auto& kv) {
      return kv.second->info.state == "done" || kv.second->info.state == "failed";
    });
    if (it == clips_.end()) break;
    if (it->second->encoder.joinable()) it->second->encoder.join();
    if (!it->second->info.path.empty()) std::remove(it->second->info.path.c_str());
    clips_.erase(it);
  }
  c->info.id = nextClip_++;
  Clip& ref = *c;
  clips_[c->info.id] = std::move(c);
  if (mode == "last") {
    startEncoding(ref);
  } else {
    ref.info.state = "recording";
    ++recording_;
  }
  return ref.info.id;
}

void LiveSession::startEncoding(Clip& c) {
  c.info.state = "encoding";
  c.info.frames = static_cast<int>(c.jpegs.size());
  const std::string path = config_.clipFolder + "/clip-" + std::to_string(c.info.id) + ".mp4";
  c.encoder = std::thread([this, &c, path] {
    std::string error;
    long long bytes = 0;
    try {
      VideoOptions vo;
      vo.fps = config_.fps;
      vo.crf = 23;
      VideoSink sink(config_.ffmpeg, path, config_.width, config_.height, vo);
      for (const auto& j : c.jpegs) {
        const Image frame = decodeImage(j->data(), j->size());
        // Frames drawn smaller while the drawing could not keep up (adaptSize) at the clip's size.
        if (frame.width == config_.width && frame.height == config_.height)
          sink.write(frame);
        else
          sink.write(resized(frame, config_.width, config_.height));
      }
      sink.commit();
      std::error_code ec;
      bytes = static_cast<long long>(std::filesystem::file_size(path, ec));
    } catch (const std::exception& e) {
      error = e.what();
    }
    std::lock_guard<std::mutex> lk(clipM_);
    c.jpegs.clear();
    c.jpegs.shrink_to_fit();
    c.info.state = error.empty() ? "done" : "failed";
    c.info.error = error;
    c.info.bytes = bytes;
    if (error.empty()) c.info.path = path;
  });
}

std::optional<ClipInfo> LiveSession::clip(int id) const {
  std::lock_guard<std::mutex> lk(clipM_);
  const auto it = clips_.find(id);
  if (it == clips_.end()) return std::nullopt;
  return it->second->info;
}

std::vector<ClipInfo> LiveSession::clips() const {
  std::lock_guard<std::mutex> lk(clipM_);
  std::vector<ClipInfo> v;
  for (const auto& [id, c] : clips_) v.push_back(c->info);
  return v;
}

}  // namespace substep::render
