// What `substep render` and `substep snapshot` share: the command-line options that say which
// panels of a scene to step and how to draw them, checked and made into a RenderSession and a
// renderer, and the stepping of a single frame far into a run with progress and Ctrl-C.
#pragma once

#include "app/recordings.h"

#include "app/common.h"
#include "render/gl_renderer.h"
#include "render/session.h"

#include <CLI/CLI.hpp>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace substep::app {

struct RenderOptions {
  std::string scene, panels, size, colour = "auto", camera;
  std::optional<std::string> follow;
  SolverOptions solver;
  std::optional<double> yaw, pitch, distance, fov;
  std::vector<double> target;
  std::vector<std::string> highlight;
  double orbit = 0, speedScale = 5, errorScale = 0.01, forceScale = 0;
  int samples = 1, shadowSize = 1024;
  std::optional<std::string> antiAliasing;  // --aa; default fxaa without multisampling, none with it
  bool contacts = false, joints = false, forces = false, jointErrors = false, noHud = false, quiet = false;
  CLI::Option* panelsOption_ = nullptr;  // to tell "--compare ''" from no --compare

  // Adds the scene (positional), the solver options and the drawing options to `cmd`. The
  // panels' option is named by `panelsFlags` ("--compare,--panels" for render); `sizeDefault`
  // is --size's default. Returns the scene's option, so a command may make it optional.
  CLI::Option* add(CLI::App& cmd, const std::string& panelsFlags, const std::string& sizeDefault);

  render::ColourMode colourMode() const;  // --color; throws UsageError
  // The session of the scene: the panels (one, or one per --compare setting over the shared
  // solver options), the camera, what is drawn; `stepCost` puts the measured step cost in the HUD.
  render::RenderSession makeSession(std::shared_ptr<const Scene> scene, bool stepCost) const;
  // A recording's session instead (`scene` names a .rec): its panels and frames, replayed, not
  // stepped; solver options and --compare are refused (a recording has its own). UsageError.
  render::RenderSession makeRecordedSession(const OpenedRecording& rec) const;
  render::Look look(const Scene& scene, bool stepCost) const;           // the camera and what is drawn
  std::vector<render::PanelSetup> panelSetups(const Scene& scene) const;  // a panel's settings each
  std::unique_ptr<render::GlRenderer> makeRenderer(int width, int height) const;

  // "scene ..." and one "solver ..." line per panel, unless --quiet.
  void printHeader(const render::RenderSession& session) const;
};

// WIDTHxHEIGHT, 16x16 to 7680x4320. Throws UsageError naming --size.
void parseFrameSize(const std::string& size, int& width, int& height);

// After Ctrl-C or SIGTERM (an InterruptGuard lives while frames are made): throws Interrupted
// (exit status 130), so the sinks remove their temporaries on the way out.
void stopIfInterrupted();

// Steps the session to `t` in half-second chunks with a progress bar over the steps (unless
// quiet), for a single frame far into a run. Stops early when a panel diverges or on Ctrl-C.
void advanceShowingSteps(render::RenderSession& session, double t, bool quiet);

// The message and status of a diverged panel: "PROGRAM: stopped: ...; no output written", 3 (2
// when its algorithm refused the scene: bad input).
int reportDivergence(const char* program, const render::Panel& panel);

}  // namespace substep::app
