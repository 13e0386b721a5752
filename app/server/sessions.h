// The sessions of `substep serve`, one per browser tab: what the API keeps of each (the scene by
// name, each panel's method and the user's changes) around its LiveSession, and the registry that
// opens them within the server's limit, finds them by id, closes idle ones (the reaper) and caches
// the scene files they load. Apart from HTTP, so that its locking can be read on its own: the
// registry's lock guards the map only, a session's own lock its scene and panels.
#pragma once

#include "app/server.h"
#include "app/server/http.h"
#include "app/recordings.h"
#include "app/server/inspect.h"
#include "render/live_session.h"

#include <atomic>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace substep::app::web {

using render::LiveConfig;
using render::LiveSession;
using render::Look;
using render::PanelSetup;

// A session of the API: the scene by name, the method of each panel with the settings the user
// changed, and the live session that steps and draws them.
struct WebSession {
  struct PanelState {
    SolverOverrides user;  // the method's settings and the user's changes over the scene's
    std::string recorded;  // a recorded panel: its method as the recording names it
    std::string method() const { return recorded.empty() ? user.specText() : recorded; }
  };
  std::string id;
  std::mutex m;  // scene, panels (the live session has its own lock)
  std::string sceneName;
  std::shared_ptr<const Scene> scene;
  std::vector<PanelState> panels;
  std::string clipFolder;
  int selected = -1;                          // the inspected body (highlighted), -1 for none
  std::shared_ptr<SessionTimeline> timeline;  // before `live`: its hook runs while `live` does
  std::unique_ptr<LiveSession> live;
};

class Sessions {
 public:
  // `scratch`: the folder for the sessions' clips; `ffmpeg`: "" when clips cannot be made.
  Sessions(const ServerOptions& o, std::string scratch, std::string ffmpeg);
  ~Sessions();  // stop()
  Sessions(const Sessions&) = delete;
  Sessions& operator=(const Sessions&) = delete;

  // The scene files of the scenes folder, by name, sorted.
  std::vector<std::string> sceneNames() const;
  // A scene by name, loaded once; HttpError 400 naming `field` for a name not in the folder,
  // 500 for a file that does not load.
  std::shared_ptr<const Scene> scene(const std::string& name, const std::string& field);

  // The recordings it can open, by name: --open files (their file name), the lab folder's .rec
  // files (their path in it) and uploads ("upload/N-name.rec"). Sorted, at most 500.
  struct KnownRecording {
    std::string name, path;
    long long bytes = 0;
  };
  std::vector<KnownRecording> recordings() const;
  // A recording by name, read once (the last few are kept); HttpError 400 naming `field` for an
  // unknown name or a damaged file (the reader's reason).
  std::shared_ptr<const OpenedRecording> recording(const std::string& name, const std::string& field);
  // An uploaded recording: checked whole, kept in the scratch folder; its name. HttpError 400.
  std::string upload(const std::string& bytes, const std::string& fileName);

  // What a new session's live session starts from: the server's frame size, fps, JPEG quality,
  // history and ffmpeg, and the draw and encode gates all sessions share.
  LiveConfig config() const;
  bool canRecord() const { return !ffmpeg_.empty(); }

  // Gives `s` an id and a clip folder, starts its live session (playing at `play` if given) and
  // registers it. HttpError 503 when stopping or at the limit, 400 for a panel that cannot start.
  // `prepare`, when given, changes the render session before it plays (a recording's frames).
  using Prepare = std::function<void(render::RenderSession&, Look&)>;
  void open(const std::shared_ptr<WebSession>& s, const std::vector<PanelSetup>& panels, const Look& look,
            LiveConfig config, std::optional<double> play, const Prepare& prepare = {});
  // The open session `id`, marked as used now; HttpError 404 if none.
  std::shared_ptr<WebSession> find(const std::string& id);
  bool isOpen(const std::string& id) const;
  size_t count() const;
  // Closes and forgets `id` (nothing if it is not open); `why` goes to the log.
  void remove(const std::string& id, const std::string& why);
  // The 404 of an id that names no open session.
  HttpError noSuchSession(const std::string& id) const;

  // Closes sessions idle for longer than the idle timeout, on a thread of its own, until stop().
  void startReaper();
  // Ends the reaper and closes every session (their streams end). False if already stopping.
  bool stop();
  bool stopping() const { return stopping_; }

 private:
  void close(const std::shared_ptr<WebSession>& s, const std::string& why);
  void reap();

  const ServerOptions& o_;
  const std::string scratch_, ffmpeg_;
  std::atomic<bool> stopping_{false};
  mutable std::mutex m_;
  std::map<std::string, std::shared_ptr<WebSession>> sessions_;
  std::mutex scenesM_;
  std::map<std::string, std::shared_ptr<const Scene>> sceneCache_;
  mutable std::mutex recordingsM_;
  std::vector<std::pair<std::string, std::shared_ptr<const OpenedRecording>>> recordingCache_;  // newest last
  std::vector<KnownRecording> uploads_;
  int nextUpload_ = 1;
  // One frame drawn at a time (llvmpipe uses both cores) and one JPEG encoded, whichever session.
  std::shared_ptr<render::FairGate> drawGate_ = std::make_shared<render::FairGate>(1),
                                    encodeGate_ = std::make_shared<render::FairGate>(1);
  std::thread reaper_;
  std::mutex reaperM_;
  std::condition_variable reaperCv_;
};

// A line of the server's log (stdout), whole whichever thread writes it.
void log(const std::string& line);

}  // namespace substep::app::web
