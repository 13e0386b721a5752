// The visualization server behind `substep serve`: the web page and its JSON API over HTTP
// (cpp-httplib), one LiveSession (render/live_session.h) per browser tab. docs/server.md lists
// every call.
//
// Threads: httplib's pool answers requests (a stream holds one of its threads while it lives);
// each session steps and draws on a thread of its own; a reaper closes idle sessions. A request
// for one session takes that session's lock only, so a slow or diverging session delays no other.
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace substep::app {

struct ServerOptions {
  std::string host = "127.0.0.1";
  int port = 8080;               // 0: any free port (tests)
  int maxSessions = 8;
  int width = 1280, height = 720;
  int fps = 30;
  double idleTimeout = 300;      // [s] a session with no request and no stream is closed after this
  double history = 10;           // [s] of frames kept per session for clips of the last seconds
  double timelineSeconds = 60;   // [s] of steps kept per panel to scrub back to
  int timelineMb = 512;          // at most, per session (its panels share it)
  bool adaptSize = true;         // frames drawn smaller while the drawing cannot keep the fps (LiveConfig)
  bool sleep = true;             // islands at rest sleep unless the scene or the page sets sleep
  int jpegQuality = 80;
  std::string webRoot;           // the page's files (default: the assets' web/)
  std::string scenesDir;         // scene files listed and loaded by name (default: the assets' scenes/)
  std::string labDir;            // the lab's charts and atlas, served under /lab/ ("" for none)
  size_t maxBody = 64 * 1024;    // JSON request bodies larger are refused with 413
  size_t maxUpload = size_t{512} << 20;  // an uploaded recording (POST /api/recordings) [bytes]
  std::vector<std::string> open; // recordings offered by their file name (substep serve --open)
};

class Server {
 public:
  explicit Server(ServerOptions options);  // throws UsageError for a missing web root or scenes folder
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // Binds the address; returns the port (the chosen one for port 0). Throws std::runtime_error.
  int bind();
  // Answers requests until stop(); call after bind().
  void listen();
  // Ends every stream and session, then the listener; safe from another thread.
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace substep::app
