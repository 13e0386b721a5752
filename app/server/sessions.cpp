// The session registry of `substep serve`: see sessions.h.
#include "app/server/sessions.h"

#include "app/common.h"

#include <malloc.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
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

// malloc_trim does not shrink the top of a thread's arena, and glibc makes up to 8 arenas a core
// for a server's many threads (each session steps, draws and encodes on its own, and steps on
// every core), so closed sessions left their arenas' tops behind: 8 sessions streamed and closed,
// 157-203 MiB against 67 idle. Two arenas a core: 128-156 MiB, frames/s the same (docs/server.md).
// Fixed thresholds (M_MMAP_THRESHOLD) gave 118 MiB but cost 10-30 % of the frames.
void fewerArenas() {
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  mallopt(M_ARENA_MAX, 2 * cores);
}

}  // namespace

void log(const std::string& line) {
  static std::mutex m;
  std::lock_guard<std::mutex> lk(m);
  std::cout << line << std::endl;
}

Sessions::Sessions(const ServerOptions& o, std::string scratch, std::string ffmpeg)
    : o_(o), scratch_(std::move(scratch)), ffmpeg_(std::move(ffmpeg)) {
  fewerArenas();
}

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

namespace {

constexpr size_t kCachedRecordings = 4;  // opened recordings kept (a ragdoll pile's 10 s: about 100 MB)

// A name as part of a file name: letters, digits, '.', '-', '_'.
std::string safeFileName(const std::string& name) {
  std::string s = fs::path(name).filename().string().substr(0, 80);
  for (char& c : s)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '-' && c != '_') c = '_';
  return s.empty() ? "recording.rec" : s;
}

}  // namespace

std::vector<Sessions::KnownRecording> Sessions::recordings() const {
  std::vector<KnownRecording> list;
  std::error_code ec;
  for (const std::string& path : o_.open)
    list.push_back({fs::path(path).filename().string(), path, static_cast<long long>(fs::file_size(path, ec))});
  if (!o_.labDir.empty())
    for (auto it = fs::recursive_directory_iterator(o_.labDir, ec); !ec && it != fs::recursive_directory_iterator();
         it.increment(ec)) {
      if (it->path().extension() != ".rec") continue;
      const std::string rel = fs::relative(it->path(), o_.labDir, ec).string();
      const std::string file = staticFile(o_.labDir, rel);
      if (!file.empty()) list.push_back({rel, file, static_cast<long long>(fs::file_size(file, ec))});
      if (list.size() >= 500) break;
    }
  {
    std::lock_guard<std::mutex> lk(recordingsM_);
    list.insert(list.end(), uploads_.begin(), uploads_.end());
  }
  std::sort(list.begin(), list.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  return list;
}

std::shared_ptr<const OpenedRecording> Sessions::recording(const std::string& name, const std::string& field) {
  {
    std::lock_guard<std::mutex> lk(recordingsM_);
    for (const auto& [n, r] : recordingCache_)
      if (n == name) return r;
  }
  std::string path;
  for (const KnownRecording& k : recordings())
    if (k.name == name) path = k.path;
  if (path.empty())
    throw HttpError(400, field + ": no recording " + quote(json(utf8Prefix(name, 200))) +
                             " (GET /api/recordings lists them: substep serve --open FILE, the lab folder's .rec files, uploads)");
  std::shared_ptr<const OpenedRecording> r;
  try {
    r = std::make_shared<const OpenedRecording>(openRecording(readRecording(path, o_.maxUpload)));
  } catch (const std::exception& e) {  // RecordingError, a scene that no longer parses
    throw HttpError(400, field + ": " + validUtf8(e.what()));
  }
  std::lock_guard<std::mutex> lk(recordingsM_);
  recordingCache_.emplace_back(name, r);
  if (recordingCache_.size() > kCachedRecordings) recordingCache_.erase(recordingCache_.begin());
  return r;
}

std::string Sessions::upload(const std::string& bytes, const std::string& fileName) {
  const std::string shown = safeFileName(fileName);
  std::shared_ptr<const OpenedRecording> r;
  try {
    r = std::make_shared<const OpenedRecording>(openRecording(parseRecording(bytes, shown)));
  } catch (const std::exception& e) {
    throw HttpError(400, "body: " + validUtf8(e.what()));
  }
  std::lock_guard<std::mutex> lk(recordingsM_);
  const std::string name = "upload/" + std::to_string(nextUpload_++) + "-" + shown;
  const fs::path dir = fs::path(scratch_) / "uploads";
  std::error_code ec;
  fs::create_directories(dir, ec);
  const fs::path file = dir / fs::path(name).filename();
  {
    std::ofstream out(file.string() + ".part", std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out) throw HttpError(500, "cannot keep the upload in " + dir.string());
  }
  fs::rename(file.string() + ".part", file, ec);
  if (ec) throw HttpError(500, "cannot keep the upload in " + dir.string() + ": " + ec.message());
  uploads_.push_back({name, file.string(), static_cast<long long>(bytes.size())});
  recordingCache_.emplace_back(name, r);
  if (recordingCache_.size() > kCachedRecordings) recordingCache_.erase(recordingCache_.begin());
  return name;
}

LiveConfig Sessions::config() const {
  LiveConfig c;
  c.width = o_.width;
  c.height = o_.height;
  c.fps = o_.fps;
  c.jpegQuality = o_.jpegQuality;
  c.historySeconds = o_.history;
  c.timeline = {o_.timelineSeconds, static_cast<size_t>(o_.timelineMb) << 20};
  c.adaptSize = o_.adaptSize;
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
