#include "render/session.h"

#include <algorithm>
#include <cstdio>

namespace substep::render {

namespace {

// The past is kept, not re-simulated: changing it would need the world as it was then, which a
// snapshot is not (the contact cache, warm starts).
std::invalid_argument pastError(const std::string& what, double t) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3f", t);
  return std::invalid_argument("cannot " + what + " in the past: the timeline shows t = " + buf +
                               " s; go live first (the timeline's live button, or scrub with {\"live\": true})");
}

}  // namespace

size_t snapshotBytes(const Snapshot& s) {
  return sizeof(Snapshot) + s.state.bodies.size() * sizeof(BodyState) + s.manifolds.size() * sizeof(ManifoldSnap) +
         s.contacts.size() * sizeof(ContactSnap) + s.joints.size() * sizeof(JointSnap);
}

Panel::Panel(const Scene& scene, PanelSetup setup)
    : setup_(std::move(setup)),
      world_(std::make_unique<World>(scene.model, setup_.settings, scene.initial)),
      engine_(std::make_unique<WorldEngine>(*world_)),
      run_(std::make_unique<RunDriver>(*engine_, std::numeric_limits<long long>::max())) {
  keep(takeSnapshot(scene.model, world_->state()));
}

Panel::Panel(const Scene& scene, PanelSetup setup, std::vector<Snapshot> frames) : Panel(scene, std::move(setup)) {
  if (frames.empty()) throw std::invalid_argument("a recorded panel needs at least one frame");
  recorded_ = true;
  history_.clear();
  historyBytes_ = 0;
  limits_ = {std::numeric_limits<double>::infinity(), std::numeric_limits<size_t>::max()};  // a recording is kept whole
  for (Snapshot& f : frames) keep(std::move(f));
  cursor_ = 0;  // from its start
}

void Panel::keep(Snapshot s) {
  historyBytes_ += snapshotBytes(s);
  history_.push_back(std::move(s));
  if (onKeep_) onKeep_(history_.back());
  trim();
}

void Panel::setLimits(const HistoryLimits& limits) {
  limits_ = limits;
  trim();
}

void Panel::trim() {
  if (history_.empty()) return;  // nothing kept yet (limits set before the first step)
  const double newest = history_.back().state.time;
  // The oldest go while the past exceeds the limits (the newest stays whatever it costs).
  while (history_.size() > 1 && (history_.front().state.time < newest - limits_.seconds - 1e-9 || historyBytes_ > limits_.bytes)) {
    historyBytes_ -= snapshotBytes(history_.front());
    history_.pop_front();
    if (cursor_) *cursor_ = *cursor_ > 0 ? *cursor_ - 1 : 0;
  }
  if (cursor_ && *cursor_ + 1 >= history_.size()) cursor_.reset();  // the newest is live
}

bool Panel::takeStep() {
  if (!run_->stepOnce()) {
    const RunOutcome& o = run_->outcome();
    diverged_ = true;
    refused_ = o.end == RunOutcome::End::Refused;
    divergedAt_ = world_->state().time;
    problem_ = (name().empty() ? std::string() : "panel \"" + name() + "\": ") + o.message;
    return false;
  }
  const StepReport& r = world_->lastReport();
  costSum_ += r.times.total();
  physicsSeconds_ += r.times.total();
  ++costSteps_;
  ++steps_;
  keep(takeSnapshot(*world_));
  return true;
}

void Panel::view(double t) {
  // The newest kept at or before t (times increase along the history).
  const double eps = 0.5 * world_->settings().dt;
  size_t lo = 0, hi = history_.size();  // first index with time > t + eps
  while (lo < hi) {
    const size_t mid = (lo + hi) / 2;
    if (history_[mid].state.time > t + eps) hi = mid; else lo = mid + 1;
  }
  const size_t k = lo == 0 ? 0 : lo - 1;
  if (k + 1 == history_.size()) cursor_.reset(); else cursor_ = k;
}

void Panel::moveCursor(long long by) {
  const long long last = static_cast<long long>(history_.size()) - 1;
  const long long k = std::clamp<long long>(cursor() + by, 0, last);
  if (k == last) cursor_.reset(); else cursor_ = static_cast<size_t>(k);
}

void Panel::advanceTo(double t) {
  const double dt = world_->settings().dt;
  if (cursor_) {  // the kept past first: replayed, not stepped again
    view(t);
    if (cursor_ || recorded_ || history_.back().state.time + 0.5 * dt > t) return;
  }
  if (diverged_ || recorded_) return;
  while (world_->state().time + 0.5 * dt <= t)
    if (!takeStep()) return;
  if (costSteps_ > 0) lastStepMs_ = 1e3 * costSum_ / costSteps_;
  costSum_ = 0;
  costSteps_ = 0;
}

void Panel::stepOnce() {
  if (cursor_) {
    moveCursor(1);
    return;
  }
  if (diverged_ || recorded_) return;
  if (takeStep()) lastStepMs_ = 1e3 * costSum_;
  costSum_ = 0;
  costSteps_ = 0;
}

RenderSession::RenderSession(std::shared_ptr<const Scene> scene, const std::vector<PanelSetup>& panels, Look look)
    : scene_(std::move(scene)), look_(std::move(look)) {
  setPanels(panels);
}

void RenderSession::hookPanel(int i) {
  Panel& p = *panels_[static_cast<size_t>(i)];
  if (!p.recorded_) p.setLimits(panelLimits());
  if (!hook_) {
    p.onKeep_ = nullptr;
    return;
  }
  for (const Snapshot& s : p.history_) hook_(i, scene_, s);
  p.onKeep_ = [this, i](const Snapshot& s) { hook_(i, scene_, s); };
}

void RenderSession::setSnapshotHook(SnapshotHook hook) {
  hook_ = std::move(hook);
  for (int i = 0; i < panelCount(); ++i) hookPanel(i);
}

void RenderSession::setHistoryLimits(const HistoryLimits& limits) {
  limits_ = limits;
  for (auto& p : panels_)
    if (!p->recorded_) p->setLimits(panelLimits());
}

void RenderSession::view(double t) {
  for (auto& p : panels_) p->view(t);
}

void RenderSession::viewBy(long long k) {
  panels_[0]->moveCursor(k);
  const double t = panels_[0]->state().time;
  for (size_t i = 1; i < panels_.size(); ++i) panels_[i]->view(t);
}

void RenderSession::viewLive() {
  for (auto& p : panels_) p->cursor_.reset();
}

bool RenderSession::live() const {
  for (const auto& p : panels_)
    if (!p->live()) return false;
  return true;
}

bool RenderSession::ended() const {
  for (const auto& p : panels_)
    if (!p->ended()) return false;
  return true;
}

double RenderSession::firstKept() const {
  double t = -std::numeric_limits<double>::infinity();
  for (const auto& p : panels_) t = std::max(t, p->history_.front().state.time);
  return t;
}

double RenderSession::lastKept() const { return panels_[0]->history_.back().state.time; }

void RenderSession::setRecorded(std::shared_ptr<const Scene> scene, const std::vector<PanelSetup>& panels,
                                std::vector<std::vector<Snapshot>> frames) {
  if (frames.size() != panels.size()) throw PanelError(0, "a recorded session needs one list of frames per panel");
  std::vector<std::unique_ptr<Panel>> made;
  for (size_t i = 0; i < panels.size(); ++i) {
    try {
      made.push_back(std::make_unique<Panel>(*scene, panels[i], std::move(frames[i])));
    } catch (const std::invalid_argument& e) {
      throw PanelError(static_cast<int>(i), e.what());
    }
  }
  panels_ = std::move(made);
  scene_ = std::move(scene);
  for (int i = 0; i < panelCount(); ++i) hookPanel(i);
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
  for (int i = 0; i < panelCount(); ++i) hookPanel(i);
}

void RenderSession::setPanel(int i, const PanelSetup& setup) {
  try {
    panels_[static_cast<size_t>(i)] = std::make_unique<Panel>(*scene_, setup);
    hookPanel(i);
  } catch (const std::invalid_argument& e) {
    throw PanelError(i, e.what());
  }
}

void RenderSession::setSettings(int i, const SolverSettings& settings) {
  Panel& p = *panels_[static_cast<size_t>(i)];
  if (p.recorded_) throw std::invalid_argument("a recording's settings are what it was recorded with; they cannot change");
  if (!p.live()) throw pastError("change the settings", p.state().time);
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
  // The step shown, with its own contacts (a diverged panel's: its last finite step's); another
  // state has none.
  const Snapshot other = state ? takeSnapshot(scene_->model, *state) : Snapshot{};
  ViewOptions view = look_.view;
  view.impulseTime = impulseTime(p.settings());
  DrawList dl = buildDrawList(scene_->model, state ? other : p.shown(), cam, view, hud);
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
  if (recorded()) throw std::invalid_argument("a recording is replayed as it was: its bodies cannot be pushed");
  if (!live()) throw pastError("push a body", time());
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
