// substep serve: the interactive visualization server (app/server.h, docs/server.md). Binds
// loopback unless told otherwise, prints its address, answers until Ctrl-C or SIGTERM.
#include "app/commands.h"
#include "app/common.h"
#include "app/recordings.h"
#include "app/render_options.h"
#include "app/server.h"

#include <signal.h>

#include <iostream>
#include <thread>

namespace substep::app {

void addServeCommand(CLI::App& app, std::function<int()>& action) {
  auto o = std::make_shared<ServerOptions>();
  auto size = std::make_shared<std::string>("1280x720");
  auto uploadMb = std::make_shared<int>(512);
  CLI::App* cmd = app.add_subcommand("serve", "Serve the interactive web page: drive and watch scenes from a browser");
  cmd->footer(
      "\nOpen the printed address in a browser. On a remote machine, forward the port first:\n"
      "  ssh -L 8080:127.0.0.1:8080 user@host     then open http://127.0.0.1:8080/ on the laptop\n"
      "There is no authentication: --host other than loopback lets anyone who reaches the address drive it.\n"
      "The JSON API is in docs/server.md. Ctrl-C (or SIGTERM) stops the server (exit status 130).");
  cmd->add_option("--host", o->host, "Address to listen on (default 127.0.0.1: this machine only)");
  cmd->add_option("--port", o->port, "Port (default 8080; 0 picks a free one)")->check(CLI::Range(0, 65535));
  cmd->add_option("--max-sessions", o->maxSessions, "Sessions (browser tabs) at once; more get 503 (default 8)")
      ->check(CLI::Range(1, 64));
  cmd->add_option("--size", *size, "Frame size of new sessions WIDTHxHEIGHT (default 1280x720, at most 1920x1080)");
  cmd->add_option("--fps", o->fps, "Frames per second streamed to each session (default 30)")->check(CLI::Range(1, 60));
  cmd->add_option("--idle-timeout", o->idleTimeout,
                  "Close a session after this long without a request or a stream [s] (default 300)")
      ->check(finiteIn(0.1, 86400));
  cmd->add_option("--history", o->history, "Seconds of frames each session keeps for clips of the last seconds (default 10)")
      ->check(finiteIn(0, 60));
  cmd->add_option("--timeline", o->timelineSeconds,
                  "Seconds of steps each session keeps to scrub back to on the timeline (default 60)")
      ->check(finiteIn(0, 3600));
  cmd->add_option("--timeline-mb", o->timelineMb,
                  "At most this many MB of kept steps per session, shared by its panels; the oldest go first (default 512)")
      ->check(CLI::Range(1, 65536));
  cmd->add_flag("!--no-sleep", o->sleep,
                "Keep every island awake (default: islands at rest for half a second sleep unless the scene or the page "
                "sets sleep; the activity colours show them dark blue)");
  cmd->add_flag("!--fixed-size", o->adaptSize,
                "Draw every frame at --size (default: a session whose drawing cannot keep --fps draws at 3/4, then 1/2 of it, "
                "and says so in its stats, so the page stays interactive)");
  cmd->add_option("--quality", o->jpegQuality, "JPEG quality of the stream, 1-100 (default 80)")->check(CLI::Range(1, 100));
  cmd->add_option("--web", o->webRoot, "Folder of the page's files (default: the assets' web/)");
  cmd->add_option("--scenes", o->scenesDir, "Folder of the scene files it offers (default: the assets' scenes/)");
  cmd->add_option("--open", o->open,
                  "A recording (substep run --record) to replay; the page opens it (repeat for more)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--max-upload-mb", *uploadMb, "Largest recording the page may upload [MB] (default 512)")
      ->check(CLI::Range(1, 65536));
  cmd->add_option("--lab", o->labDir, "Folder of the lab's charts and atlas, linked from the page and served under /lab/");
  cmd->callback([o, size, uploadMb, &action] {
    action = [o, size, uploadMb]() -> int {
      parseFrameSize(*size, o->width, o->height);
      if (o->width > 1920 || o->height > 1080 || o->width < 64 || o->height < 64)
        throw UsageError("--size " + *size + ": expected 64x64 to 1920x1080");
      if (o->labDir.empty() && std::filesystem::is_directory("out/lab")) o->labDir = "out/lab";
      o->maxUpload = static_cast<size_t>(*uploadMb) << 20;
      // Each recording read whole now: a damaged one is refused before the server starts.
      for (const std::string& r : o->open) {
        const OpenedRecording rec = openRecordingFile(r, o->maxUpload);
        std::cout << "substep serve: --open " << r << ": " << rec.scene->file << ", " << rec.panels.size() << " panel"
                  << (rec.panels.size() == 1 ? "" : "s") << ", " << rec.seconds << " s" << std::endl;
      }
      ::signal(SIGPIPE, SIG_IGN);  // a viewer gone mid-frame is an error return, not the end of the server
      InterruptGuard interrupts;
      Server server(*o);
      const int port = server.bind();
      const bool loopback = o->host == "127.0.0.1" || o->host == "localhost" || o->host == "::1";
      const std::string shown = o->host.find(':') != std::string::npos ? "[" + o->host + "]" : o->host;
      std::cout << "substep serve: http://" << shown << ":" << port << "/" << std::endl
                << "  " << o->maxSessions << " sessions at most, " << o->width << "x" << o->height << " at " << o->fps
                << " fps; Ctrl-C stops it" << std::endl;
      if (!loopback)
        std::cout << "  listening on " << o->host
                  << ": anyone who can reach this address can use the server (it has no authentication)" << std::endl;
      std::thread listener([&] { server.listen(); });
      while (!InterruptGuard::interrupted()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
      std::cout << "substep serve: " << (InterruptGuard::signal() == SIGTERM ? "SIGTERM" : "SIGINT")
                << ": closing the sessions and stopping" << std::endl;
      server.stop();
      listener.join();
      std::cout << "substep serve: stopped" << std::endl;
      return kExitInterrupted;
    };
  });
}

}  // namespace substep::app
