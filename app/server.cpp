// `substep serve`'s server (server.h): its parts put together. The parts are under app/server/:
// http (plumbing, errors, files, the router), requests (bodies read and checked), api_json (the
// answers' JSON), sessions (the registry and its reaper), streams (MJPEG, events), handlers (the
// calls) and routes (the table of paths).
#include "app/server.h"

#include "app/common.h"
#include "app/server/handlers.h"
#include "app/server/http.h"
#include "app/server/sessions.h"
#include "render/video.h"

#include <stdlib.h>
#include <sys/socket.h>

#include <filesystem>

namespace substep::app {

namespace {

namespace fs = std::filesystem;

// The options with the assets' folders for those not given; throws UsageError for folders that
// are not there.
ServerOptions checked(ServerOptions o) {
  if (o.webRoot.empty()) o.webRoot = assetsDir() + "/web";
  if (o.scenesDir.empty()) o.scenesDir = assetsDir() + "/scenes";
  std::error_code ec;
  if (!fs::is_regular_file(o.webRoot + "/index.html", ec))
    throw UsageError("--web " + o.webRoot + ": no index.html there (the page's folder is assets/web)");
  if (!fs::is_directory(o.scenesDir, ec)) throw UsageError("--scenes " + o.scenesDir + ": not a folder");
  if (!o.labDir.empty() && !fs::is_directory(o.labDir, ec)) throw UsageError("--lab " + o.labDir + ": not a folder");
  return o;
}

// A new folder for the clips of this server's sessions.
std::string scratchFolder() {
  std::error_code ec;
  std::string tmpl = (fs::temp_directory_path(ec) / "substep-serve-XXXXXX").string();
  if (!mkdtemp(tmpl.data())) throw std::runtime_error("cannot make a scratch folder for clips in " + fs::temp_directory_path(ec).string());
  return tmpl;
}

}  // namespace

struct Server::Impl {
  explicit Impl(ServerOptions options)
      : o(checked(std::move(options))),
        ffmpeg(render::findFfmpeg()),
        scratch(scratchFolder()),
        sessions(o, scratch, ffmpeg),
        router(http, o.maxBody),
        handlers(o, sessions, router) {}

  const ServerOptions o;
  const std::string ffmpeg, scratch;
  httplib::Server http;
  web::Sessions sessions;
  web::Router router;
  web::Handlers handlers;
};

Server::Server(ServerOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {
  Impl& m = *impl_;
  // Streams hold a thread each while they live: room for every session's stream, events and
  // requests at once.
  const size_t threads = static_cast<size_t>(4 * m.o.maxSessions + 16);
  m.http.new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  // Uploads are the large bodies; JSON bodies keep their own limit (web::Fields).
  m.http.set_payload_max_length(std::max(m.o.maxBody, m.o.maxUpload));
  web::setJsonBodyLimit(m.o.maxBody);
  // SO_REUSEADDR only: httplib's default adds SO_REUSEPORT, with which a second server on the
  // same port starts too and takes half the connections.
  m.http.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  m.http.set_keep_alive_timeout(2);
  m.http.set_read_timeout(10);
  m.http.set_write_timeout(10);
  web::addRoutes(m.router, m.handlers);
}

Server::~Server() {
  stop();
  std::error_code ec;
  fs::remove_all(impl_->scratch, ec);
}

int Server::bind() {
  Impl& m = *impl_;
  const int port = m.o.port == 0 ? m.http.bind_to_any_port(m.o.host) : (m.http.bind_to_port(m.o.host, m.o.port) ? m.o.port : -1);
  if (port <= 0)
    throw std::runtime_error("cannot listen on " + m.o.host + ":" + std::to_string(m.o.port) +
                             " (in use, or not an address of this machine)");
  m.sessions.startReaper();
  return port;
}

void Server::listen() { impl_->http.listen_after_bind(); }

void Server::stop() {
  if (impl_->sessions.stop()) impl_->http.stop();
}

}  // namespace substep::app
