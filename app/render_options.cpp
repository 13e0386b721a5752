#include "app/render_options.h"

#include "render/compare.h"

#include <algorithm>
#include <iostream>

namespace substep::app {

using namespace substep::render;

namespace {

constexpr int kMaxWidth = 7680, kMaxHeight = 4320, kMinSide = 16;

// A whole number of up to six digits, or -1.
int smallNumber(const std::string& s) {
  if (s.empty() || s.size() > 6 || !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return -1;
  return std::stoi(s);
}

}  // namespace

CLI::Option* RenderOptions::add(CLI::App& cmd, const std::string& panelsFlags, const std::string& sizeDefault) {
  size = sizeDefault;
  CLI::Option* sceneOpt = cmd.add_option("scene", scene, "Scene file (JSON), e.g. assets/scenes/pyramid.json, or a recording (.rec) to replay");
  solver.add(cmd);
  cmd.add_option("--size", size, "Frame size WIDTHxHEIGHT (default " + sizeDefault + ", at most 7680x4320)");
  auto* compare = cmd.add_option(panelsFlags, panels, "Draw 2-4 settings side by side, e.g. a2:m=4,a5:n=4 (see below)");
  panelsOption_ = compare;
  cmd.get_option("--algo")->excludes(compare);
  cmd.add_option("--camera", camera, "Camera preset of the scene file (default: its first, else a fitted view)");
  // Every number finite and in range: NaN passes CLI::Range, and a NaN camera draws a blank frame.
  cmd.add_option("--yaw", yaw, "Camera yaw about +Y [degrees], 0 looks along -Z")
      ->check(finiteIn(limits::kDegrees.lo, limits::kDegrees.hi));
  cmd.add_option("--pitch", pitch, "Camera pitch above the horizon [degrees]")->check(finiteIn(-89.0, 89.0));
  cmd.add_option("--distance", distance, "Camera distance from its target [m]")
      ->check(finiteIn(limits::kDistance.lo, limits::kDistance.hi));
  cmd.add_option("--fov", fov, "Vertical field of view [degrees]")->check(finiteIn(5.0, 150.0));
  cmd.add_option("--target", target, "Camera target x,y,z [m]")
      ->expected(3)
      ->delimiter(',')
      ->check(finiteIn(limits::kCoordinate.lo, limits::kCoordinate.hi));
  cmd.add_option("--follow", follow, "Keep this body at the centre of the view");
  cmd.add_option("--orbit", orbit, "Turn the camera about the target [degrees per simulated second]")
      ->check(finiteIn(-1e4, 1e4));
  cmd.add_option("--color,--colour", colour,
                 "Body colours: auto (groups, else bodies), body, group, speed, activity (resting or moving), error "
                 "(constraint error)");
  cmd.add_option("--speed-scale", speedScale, "--color speed: the speed drawn red [m/s] (default 5)")
      ->check(finiteIn(1e-9, 1e9));
  cmd.add_option("--error-scale", errorScale, "--color error: the error drawn red [m] (default 0.01)")
      ->check(finiteIn(1e-12, 1e9));
  cmd.add_option("--highlight", highlight, "Bodies to draw with a glow (names, comma separated)")->delimiter(',');
  cmd.add_flag("--contacts", contacts, "Draw contact points and normals");
  cmd.add_flag("--joints", joints, "Draw joint anchors, arms and axes");
  cmd.add_flag("--forces", forces,
               "Draw contact impulses as arrows: normal impulse at each contact point (orange), friction impulse of "
               "each touching pair (green); the legend gives the scale");
  cmd.add_flag("--joint-errors", jointErrors, "Draw each joint's error as a red segment from its anchor on A to B's");
  cmd.add_option("--force-scale", forceScale,
                 "--forces: arrow length per impulse [m per N s]; 0 (the default): the heaviest body's weight over "
                 "one step, m g dt, drawn as long as that body's radius")
      ->check(finiteIn(0.0, 1e9));
  cmd.add_flag("--no-hud", noHud, "No text overlay");
  cmd.add_option("--aa", antiAliasing,
                 "Post-process anti-aliasing: fxaa (FXAA edge blend, the default) or none (the default with --samples)")
      ->check(CLI::IsMember({"fxaa", "none"}));
  cmd.add_option("--samples", samples,
                 "Multisampling per pixel: 1 (off, the default), or 2, 4, 8 (llvmpipe draws 4: slower, finest edges)")
      ->check(CLI::IsMember({1, 2, 4, 8}));
  cmd.add_option("--shadow-size", shadowSize, "Shadow map side in texels, 0 for no shadows (default 1024)")
      ->check(CLI::Range(0, 8192));
  cmd.add_flag("--quiet,-q", quiet, "Print nothing but errors");
  return sceneOpt;
}

void parseFrameSize(const std::string& size, int& w, int& h) {
  const size_t x = size.find('x');
  w = x == std::string::npos ? -1 : smallNumber(size.substr(0, x));
  h = x == std::string::npos ? -1 : smallNumber(size.substr(x + 1));
  if (w < 0 || h < 0) throw UsageError("--size: expected WIDTHxHEIGHT, e.g. 1280x720, got \"" + size + "\"");
  if (w < kMinSide || h < kMinSide || w > kMaxWidth || h > kMaxHeight)
    throw UsageError("--size " + size + ": width must be " + std::to_string(kMinSide) + " to " + std::to_string(kMaxWidth) +
                     " and height " + std::to_string(kMinSide) + " to " + std::to_string(kMaxHeight) + " pixels (at most " +
                     std::to_string(kMaxWidth) + "x" + std::to_string(kMaxHeight) + ")");
}

ColourMode RenderOptions::colourMode() const {
  const auto c = parseColourMode(colour);
  if (!c) throw UsageError("--color: expected auto, body, group, speed, activity or error, got \"" + colour + "\"");
  return *c;
}

namespace {

CameraOptions cameraOptions(const RenderOptions& o) {
  CameraOptions c;
  c.preset = o.camera;
  c.yaw = o.yaw;
  c.pitch = o.pitch;
  c.distance = o.distance;
  c.fov = o.fov;
  if (!o.target.empty()) c.target = Vec3(o.target[0], o.target[1], o.target[2]);
  c.follow = o.follow;
  return c;
}

}  // namespace

Look RenderOptions::look(const Scene& scene, bool stepCost) const {
  Look look;
  try {
    look.camera = chooseCamera(scene, cameraOptions(*this));
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  look.orbit = orbit;
  look.stepCost = stepCost;
  for (const std::string& name : highlight)
    if (scene.model.bodyIndex(name) < 0) throw UsageError("--highlight: " + scene.file + " has no body \"" + name + "\"");
  look.view.colour = colourMode();
  look.view.contacts = contacts;
  look.view.joints = joints;
  look.view.forces = forces;
  look.view.jointErrors = jointErrors;
  look.view.forceScale = forceScale;
  look.view.hud = !noHud;
  look.view.highlight = highlight;
  look.view.speedScale = speedScale;
  look.view.errorScale = errorScale;
  return look;
}

std::vector<PanelSetup> RenderOptions::panelSetups(const Scene& scene) const {
  const SolverOverrides common = onEveryCore(scene, solver.overrides());
  if (panels.empty() && panelsOption_ && panelsOption_->count() > 0)
    throw UsageError(panelsOption_->get_name() + ": expected 2 to 4 settings, e.g. a2:m=4,a5:n=4, got nothing");
  if (panels.empty()) return {{resolveSettings(scene, common), ""}};
  std::vector<CompareSpec> specs;
  try {
    specs = parseCompareSpecs(panels);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  std::vector<PanelSetup> setups;
  for (const CompareSpec& s : specs) {
    try {
      setups.push_back({resolveSettings(scene, common.merged(s.overrides)), s.text});
    } catch (const UsageError& e) {
      throw UsageError("--compare \"" + s.text + "\": " + e.what());
    }
  }
  return setups;
}

RenderSession RenderOptions::makeSession(std::shared_ptr<const Scene> scene, bool stepCost) const {
  const Look l = look(*scene, stepCost);
  const std::vector<PanelSetup> setups = panelSetups(*scene);
  try {
    return RenderSession(std::move(scene), setups, l);
  } catch (const PanelError& e) {
    const std::string& name = setups[static_cast<size_t>(e.panel)].name;
    throw UsageError((name.empty() ? std::string() : "--compare \"" + name + "\": ") + e.what());
  }
}

RenderSession RenderOptions::makeRecordedSession(const OpenedRecording& rec) const {
  if (!panels.empty() || !solver.overrides().empty())
    throw UsageError(scene + ": a recording replays the settings it was recorded with; drop --compare and the solver options");
  RenderSession s(rec.scene, rec.panels, look(*rec.scene, false));
  try {
    s.setRecorded(rec.scene, rec.panels, rec.frames);
  } catch (const PanelError& e) {
    throw UsageError(scene + ": panel " + std::to_string(e.panel) + ": " + e.what());
  }
  return s;
}

std::unique_ptr<GlRenderer> RenderOptions::makeRenderer(int width, int height) const {
  RendererOptions ro;
  ro.samples = samples;
  ro.antiAliasing = antiAliasing ? *parseAntiAliasing(*antiAliasing) : (samples > 1 ? AntiAliasing::None : AntiAliasing::Fxaa);
  ro.shadowSize = shadowSize;
  try {
    return std::make_unique<GlRenderer>(width, height, ro);
  } catch (const RenderError& e) {
    throw std::runtime_error(std::string("cannot render: ") + e.what());
  }
}

void RenderOptions::printHeader(const RenderSession& session) const {
  if (quiet) return;
  const Scene& s = session.scene();
  std::cout << "scene     " << s.file << " (" << s.model.dynamicCount() << " dynamic bodies, " << s.model.joints.size()
            << " joints)\n";
  for (int i = 0; i < session.panelCount(); ++i) std::cout << "solver    " << settingsLine(session.panel(i).settings()) << "\n";
}

void stopIfInterrupted() {
  if (InterruptGuard::interrupted()) throw Interrupted();
}

void advanceShowingSteps(RenderSession& session, double t, bool quiet) {
  // Half-second chunks, so the progress bar moves during a long simulation.
  const double dt = session.panel(0).settings().dt;
  Progress steps("simulate", std::max(1LL, std::llround(t / dt)));
  for (double tc = std::min(t, 0.5);; tc = std::min(t, tc + 0.5)) {
    stopIfInterrupted();
    session.advanceTo(tc);
    if (session.firstDiverged()) return;
    if (!quiet) steps.update(std::llround(tc / dt));
    if (tc >= t) break;
  }
  if (!quiet) steps.finish();
}

int reportDivergence(const char* program, const Panel& panel) {
  std::cerr << program << ": stopped: " << panel.problem() << "; no output written\n";
  return panel.refused() ? kExitBadInput : kExitNonFinite;
}

}  // namespace substep::app
