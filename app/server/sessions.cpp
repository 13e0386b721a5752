// The session registry of `substep serve`: see sessions.h.
#include "app/server/sessions.h"

#include "app/common.h"

#include <malloc.h>

#include <filesystem>
#include <iostream>
#include <random>

namespace substep::app::web {

namespace fs = std::filesystem;

namespace {

std::string randomId() {
  static std::mutex m;
  static std::mt19937_64 rng(std::random_device{}());
  std::lock_guard<std::mutex> lk(m);
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(rng()));
  return buf;
}

// glibc keeps what frames freed (megabytes each, from many threads) for reuse rather than giving
// it back; a closed session's memory, and what streaming leaves free, go back to the system.
void trimMemory() { malloc_trim(0); }

}  // namespace

void log(const std::string& line) {
  static std::mutex m;
  std::lock_guard<std::mutex> lk(m);
  std::cout << line << std::endl;
}

Sessions::Sessions(const ServerOptions& o, std::string scratch, std::string ffmpeg)
    : o_(o), scratch_(std::move(scratch)), ffmpeg_(std::move(ffmpeg)) {}

Sessions::~Sessions() { stop(); }

// --- scenes ---

std::vector<std::string> Sessions::sceneNames() const {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(o_.scenesDir, ec))
    if (e.path().extension() == ".json" && e.is_regular_file()) names.push_back(e.path().stem().string());
  std::sort(names.begin(), names.end());
  return names;
}

std::shared_ptr<const Scene> Sessions::scene(const std::string& name, const std::string& field) {
  const std::vector<std::string> names = sceneNames();
  if (std::find(names.begin(), names.end(), name) == names.end())
    throw HttpError(400, field + ": expected one of " + joined(names) + ", got " + quote(json(name)));
  std::lock_guard<std::mutex> lk(scenesM_);
  auto& s = sceneCache_[name];
  if (!s) {
    try {
      s = std::make_shared<const Scene>(loadScene(o_.scenesDir + "/" + name + ".json"));
    } catch (const SceneError& e) {
      throw HttpError(500, std::string("scene ") + name + " does not load: " + e.what());
    }
  }
  return s;
}

// --- sessions ---

LiveConfig Sessions::config() const {
  LiveConfig c;
  c.width = o_.width;
  c.height = o_.height;
  c.fps = o_.fps;
  c.jpegQuality = o_.jpegQuality;
  c.historySeconds = o_.history;
  c.timeline = {o_.timelineSeconds, static_cast<size_t>(o_.timelineMb) << 20};
  c.ffmpeg = ffmpeg_;
  c.drawGate = drawGate_;
  c.encodeGate = encodeGate_;
  return c;
}

void Sessions::open(const std::shared_ptr<WebSession>& s, const std::vector<PanelSetup>& panels, const Look& look,
                    LiveConfig config, std::optional<double> play, const Prepare& prepare) {
  std::lock_guard<std::mutex> lk(m_);
  if (stopping_) throw HttpError(503, "the server is stopping");
  if (static_cast<int>(sessions_.size()) >= o_.maxSessions)
    throw HttpError(503,
                    "the server holds its limit of " + std::to_string(o_.maxSessions) +
                        " sessions (--max-sessions); close another tab, or wait for an idle one to expire (" +
                        numberText(o_.idleTimeout) + " s)",
                    {{"Retry-After", "10"}});
  do s->id = randomId();
  while (sessions_.count(s->id));
  s->clipFolder = scratch_ + "/" + s->id;
  fs::create_directories(s->clipFolder);
  config.clipFolder = s->clipFolder;
  try {
    s->live = std::make_unique<LiveSession>(s->scene, panels, look, config);
  } catch (const render::PanelError& e) {
    throw HttpError(400, e.what());
  }
  if (!s->timeline) s->timeline = std::make_shared<SessionTimeline>();
  s->live->change([&](render::RenderSession& r, Look&) { r.setSnapshotHook(s->timeline->hook()); });
  if (prepare) {
    try {
      s->live->restart([&](render::RenderSession& r, Look& look) { prepare(r, look); });
    } catch (const render::PanelError& e) {
      s->live->close();
      throw HttpError(400, e.what());
    }
  }
  if (play) s->live->play(*play);
  sessions_[s->id] = s;
  log("session " + s->id + " opened: " + s->sceneName + ", " + std::to_string(sessions_.size()) + " open");
}

HttpError Sessions::noSuchSession(const std::string& id) const {
  return HttpError(404, "no session \"" + utf8Prefix(id, 40) + "\" (closed, or expired after " +
                            numberText(o_.idleTimeout) + " s without a request or a stream)");
}

std::shared_ptr<WebSession> Sessions::find(const std::string& id) {
  std::lock_guard<std::mutex> lk(m_);
  const auto it = sessions_.find(id);
  if (it == sessions_.end()) throw noSuchSession(id);
  it->second->live->touch();
  return it->second;
}

bool Sessions::isOpen(const std::string& id) const {
  std::lock_guard<std::mutex> lk(m_);
  return sessions_.count(id) > 0;
}

size_t Sessions::count() const {
  std::lock_guard<std::mutex> lk(m_);
  return sessions_.size();
}

void Sessions::close(const std::shared_ptr<WebSession>& s, const std::string& why) {
  s->live->close();
  std::error_code ec;
  fs::remove_all(s->clipFolder, ec);
  log("session " + s->id + " closed (" + why + ")");
  trimMemory();
}

void Sessions::remove(const std::string& id, const std::string& why) {
  std::shared_ptr<WebSession> s;
  {
    std::lock_guard<std::mutex> lk(m_);
    const auto it = sessions_.find(id);
    if (it == sessions_.end()) return;
    s = it->second;
    sessions_.erase(it);
  }
  close(s, why);
}

// --- the reaper, stopping ---

void Sessions::startReaper() {
  reaper_ = std::thread([this] { reap(); });
}

void Sessions::reap() {
  std::unique_lock<std::mutex> lk(reaperM_);
  double lastTrim = nowSeconds();
  while (!stopping_) {
    reaperCv_.wait_for(lk, std::chrono::milliseconds(250));
    if (nowSeconds() - lastTrim > 5) {
      trimMemory();
      lastTrim = nowSeconds();
    }
    std::vector<std::string> idle;
    {
      std::lock_guard<std::mutex> sl(m_);
      for (const auto& [id, s] : sessions_)
        if (s->live->idleSeconds() > o_.idleTimeout) idle.push_back(id);
    }
    for (const std::string& id : idle) remove(id, "idle for " + numberText(o_.idleTimeout) + " s");
  }
}

bool Sessions::stop() {
  if (stopping_.exchange(true)) return false;
  reaperCv_.notify_all();
  if (reaper_.joinable()) reaper_.join();
  std::vector<std::shared_ptr<WebSession>> all;
  {
    std::lock_guard<std::mutex> lk(m_);
    for (auto& [id, s] : sessions_) all.push_back(s);
    sessions_.clear();
  }
  for (auto& s : all) close(s, "server stopping");
  return true;
}

}  // namespace substep::app::web
