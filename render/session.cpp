#include "render/session.h"

#include <cstdio>

namespace substep::render {

Panel::Panel(const Scene& scene, PanelSetup setup)
    : setup_(std::move(setup)),
      world_(std::make_unique<World>(scene.model, setup_.settings, scene.initial)),
      engine_(std::make_unique<WorldEngine>(*world_)),
      run_(std::make_unique<RunDriver>(*engine_, std::numeric_limits<long long>::max())) {}

bool Panel::takeStep() {
  if (!run_->stepOnce()) {
    const RunOutcome& o = run_->outcome();
    diverged_ = true;
    refused_ = o.end == RunOutcome::End::Refused;
    problem_ = (name().empty() ? std::string() : "panel \"" + name() + "\": ") + o.message;
    return false;
  }
  const StepReport& r = world_->lastReport();
  costSum_ += r.times.total();
  physicsSeconds_ += r.times.total();
  ++costSteps_;
  ++steps_;
  return true;
}

void Panel::advanceTo(double t) {
  if (diverged_) return;
  const double dt = world_->settings().dt;
  // A copy per advance (a frame), not per step: what a diverged panel goes on showing.
  if (world_->state().time + 0.5 * dt <= t) lastGood_ = world_->state();
  while (world_->state().time + 0.5 * dt <= t)
    if (!takeStep()) return;
  if (costSteps_ > 0) lastStepMs_ = 1e3 * costSum_ / costSteps_;
  costSum_ = 0;
  costSteps_ = 0;
}

void Panel::stepOnce() {
  if (diverged_) return;
  lastGood_ = world_->state();
  if (takeStep()) lastStepMs_ = 1e3 * costSum_;
  costSum_ = 0;
  costSteps_ = 0;
}

RenderSession::RenderSession(std::shared_ptr<const Scene> scene, const std::vector<PanelSetup>& panels, Look look)
    : scene_(std::move(scene)), look_(std::move(look)) {
  setPanels(panels);
}

const Panel* RenderSession::firstDiverged() const {
  for (const auto& p : panels_)
    if (p->diverged()) return p.get();
  return nullptr;
}

void RenderSession::advanceTo(double t) {
  for (auto& p : panels_) p->advanceTo(t);
}

void RenderSession::step() {
  for (auto& p : panels_) p->stepOnce();
}

void RenderSession::reset() {
  for (int i = 0; i < panelCount(); ++i) setPanel(i, panel(i).setup());
}

void RenderSession::setPanels(const std::vector<PanelSetup>& panels) { setScene(scene_, panels); }

void RenderSession::setScene(std::shared_ptr<const Scene> scene, const std::vector<PanelSetup>& panels) {
  std::vector<std::unique_ptr<Panel>> made;
  for (size_t i = 0; i < panels.size(); ++i) {
    try {
      made.push_back(std::make_unique<Panel>(*scene, panels[i]));
    } catch (const std::invalid_argument& e) {
      throw PanelError(static_cast<int>(i), e.what());
    }
  }
  panels_ = std::move(made);  // all or nothing; the worlds go before the scene they refer to
  scene_ = std::move(scene);
}

void RenderSession::setPanel(int i, const PanelSetup& setup) {
  try {
    panels_[static_cast<size_t>(i)] = std::make_unique<Panel>(*scene_, setup);
  } catch (const std::invalid_argument& e) {
    throw PanelError(i, e.what());
  }
}

void RenderSession::setSettings(int i, const SolverSettings& settings) {
  Panel& p = *panels_[static_cast<size_t>(i)];
  p.world_->setSettings(settings);
  p.setup_.settings = settings;
}

DrawList RenderSession::drawList(int i, const State* state) const {
  const Panel& p = panel(i);
  const State& s = state ? *state : p.state();
  const bool lone = panels_.size() == 1;
  HudInfo hud;
  if (lone) {
    hud.scene = sceneLine(*scene_);
    hud.settings = settingsLine(p.settings(), LineDetail::Hud);
  }  // a grid panel's label names its settings; its HUD keeps to time and cost
  hud.time = s.time;
  if (look_.stepCost) hud.stepMs = p.lastStepMs();
  if (p.diverged()) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "diverged at t = %.3f s", p.world().state().time);
    hud.status = buf;
  }
  const Camera cam = placeCamera(look_.camera, scene_->model, s, look_.orbit);
  // A diverged world's contacts belong to its non-finite state, and another state has none of them.
  const Snapshot snap = state || p.diverged() ? takeSnapshot(scene_->model, s) : takeSnapshot(p.world());
  ViewOptions view = look_.view;
  view.impulseTime = impulseTime(p.settings());
  DrawList dl = buildDrawList(scene_->model, snap, cam, view, hud);
  if (!lone) dl.label = settingsLine(p.settings(), LineDetail::Brief);
  return dl;
}

RenderSession::Pick RenderSession::pick(int width, int height, double x, double y) const {
  Pick r;
  const std::vector<Viewport> grid = gridLayout(width, height, panelCount());
  for (size_t i = 0; i < grid.size(); ++i) {
    const Viewport& v = grid[i];
    if (x < v.x || y < v.y || x >= v.x + v.width || y >= v.y + v.height) continue;
    const Panel& p = panel(static_cast<int>(i));
    const Camera cam = placeCamera(look_.camera, scene_->model, p.state(), look_.orbit);
    // The pixel's centre back through the panel's projection, near plane to far plane.
    const float aspect = static_cast<float>(v.width) / static_cast<float>(v.height);
    const Mat4f inv = (cam.projection(aspect) * cam.view()).inverse();
    const float nx = static_cast<float>(2 * (x - v.x) / v.width - 1), ny = static_cast<float>(1 - 2 * (y - v.y) / v.height);
    auto unproject = [&](float z) {
      const Vec4f h = inv * Vec4f(nx, ny, z, 1);
      return Vec3f(h.head<3>() / h.w());
    };
    const Vec3f a = unproject(-1), b = unproject(1);
    r.panel = static_cast<int>(i);
    r.origin = a.cast<double>();
    r.direction = (b - a).cast<double>().normalized();  // unit in double, not only in float
    // Against the state drawn (a diverged panel's last good one), not the world's.
    r.hit = raycast(scene_->model, p.state(), r.origin, r.direction, (b - a).norm(), true);
    break;
  }
  return r;
}

void RenderSession::push(int from, int body, const Vec3& impulse, const Vec3& point) {
  const BodyState& b = panel(from).state().bodies.at(static_cast<size_t>(body));
  const Vec3 local = b.q.conjugate() * (point - b.x);
  for (auto& p : panels_) {
    if (p->diverged()) continue;
    const BodyState& pb = p->world_->state().bodies[static_cast<size_t>(body)];
    p->world_->applyImpulse(body, impulse, pb.x + pb.q * local);
  }
}

std::vector<DrawList> RenderSession::drawLists() const {
  std::vector<DrawList> lists;
  lists.reserve(panels_.size());
  for (int i = 0; i < panelCount(); ++i) lists.push_back(drawList(i));
  return lists;
}

void RenderSession::frame(GlRenderer& renderer, Image& out) const {
  const std::vector<DrawList> lists = drawLists();
  renderer.render(gridViews(lists, renderer.width(), renderer.height()), out);
}

Image RenderSession::frame(GlRenderer& renderer) const {
  Image img;
  frame(renderer, img);
  return img;
}

std::vector<View> gridViews(const std::vector<DrawList>& lists, int width, int height) {
  const std::vector<Viewport> grid = gridLayout(width, height, static_cast<int>(lists.size()));
  std::vector<View> views;
  views.reserve(lists.size());
  for (size_t i = 0; i < lists.size(); ++i) views.push_back({&lists[i], grid[i]});
  return views;
}

}  // namespace substep::render
