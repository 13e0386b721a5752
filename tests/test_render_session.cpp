// The render session (render/session.h), the unit `substep render`, `substep snapshot`, the
// snapshot tests and the render benchmark share: panels stepped to a time, per-panel cost and
// divergence, panels replaced or re-set, the camera and the HUD changed between frames.
#include "physics/scene_file.h"
#include "render/ahead.h"
#include "render/gl_renderer.h"
#include "render/session.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

using namespace substep;
using namespace substep::render;

namespace {

std::shared_ptr<const Scene> sceneFile(const std::string& name) {
  return std::make_shared<const Scene>(loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/" + name));
}

// A 5 kg beam welded to a wall. A5 with one warm-started sweep per sub-step diverges on it near
// t = 1.2 s; cold, it holds (test_joints: WarmStart.OneSweepPerSubStepDivergesOnAFixedJoint).
std::shared_ptr<const Scene> weldedBeam() {
  return std::make_shared<const Scene>(parseScene(R"({"bodies": [
      {"name": "wall", "static": true, "shape": {"type": "box", "half_extents": [0.1, 1, 1]}, "position": [0, 3, 0]},
      {"name": "beam", "shape": {"type": "box", "half_extents": [1, 0.1, 0.1]}, "position": [1.1, 3, 0], "mass": 5}],
    "joints": [{"type": "fixed", "bodies": ["wall", "beam"], "anchor": [0.1, 3, 0]}]})",
                                                  "beam.json", "."));
}

SolverSettings settings(Algorithm a, bool warm = false) {
  SolverOverrides o;
  o.set(&SolverSettings::algorithm, a);
  o.set(&SolverSettings::warmStart, warm);
  return resolve(o);
}

bool hudHas(const DrawList& dl, const std::string& part) {
  for (const TextLine& l : dl.hud)
    if (l.text.find(part) != std::string::npos) return true;
  return false;
}

}  // namespace

// Panels step to the step nearest the time asked, only forward; step() takes one, reset() starts over.
TEST(RenderSession, AdvancesToTheNearestStepOnlyForward) {
  RenderSession s(sceneFile("stack.json"), {{settings(Algorithm::A2), ""}});
  ASSERT_EQ(s.panelCount(), 1);
  EXPECT_EQ(s.panel(0).state().step, 0);
  EXPECT_TRUE(std::isnan(s.panel(0).lastStepMs()));
  s.advanceTo(1.0);
  EXPECT_EQ(s.panel(0).state().step, 60);  // h = 1/60
  EXPECT_NEAR(s.panel(0).state().time, 1.0, 1e-9);
  EXPECT_EQ(s.panel(0).steps(), 60);
  EXPECT_GT(s.panel(0).lastStepMs(), 0);
  EXPECT_GT(s.panel(0).physicsSeconds(), 0);
  s.advanceTo(1.004);  // nearer to step 60 than 61
  s.advanceTo(0.5);    // back: nothing
  EXPECT_EQ(s.panel(0).state().step, 60);
  s.advanceTo(1.01);
  EXPECT_EQ(s.panel(0).state().step, 61);
  s.step();
  EXPECT_EQ(s.panel(0).state().step, 62);
  s.reset();
  EXPECT_EQ(s.panel(0).state().step, 0);
  EXPECT_EQ(s.panel(0).steps(), 0);
  EXPECT_EQ(s.firstDiverged(), nullptr);
}

// A panel that diverges is marked, names itself, the step and the body, keeps showing its last
// finite state, and stops; the other panels go on.
TEST(RenderSession, ADivergingPanelIsReportedAndTheOthersGoOn) {
  RenderSession s(weldedBeam(), {{settings(Algorithm::A5, true), "a5:warm=on"}, {settings(Algorithm::A5), "a5"}});
  s.advanceTo(2.0);
  const Panel& bad = s.panel(0);
  const Panel& good = s.panel(1);
  ASSERT_TRUE(bad.diverged());
  EXPECT_EQ(s.firstDiverged(), &bad);
  EXPECT_EQ(bad.problem().rfind("panel \"a5:warm=on\": the simulation diverged at step ", 0), 0u) << bad.problem();
  EXPECT_NE(bad.problem().find("\"beam\""), std::string::npos) << bad.problem();
  EXPECT_TRUE(bad.state().finite());
  EXPECT_LT(bad.state().time, bad.world().state().time);
  EXPECT_FALSE(good.diverged());
  EXPECT_EQ(good.state().step, 120);
  EXPECT_LT((good.state().bodies[1].x - Vec3(1.1, 3, 0)).norm(), 0.02);  // still welded

  // Drawn: the diverged panel with its status in the HUD, no contacts of its non-finite world.
  const DrawList dl = s.drawList(0);
  EXPECT_TRUE(hudHas(dl, "diverged at t = ")) << dl.hud.back().text;
  EXPECT_EQ(dl.label, "a5 n=4 m=1 κ=1 τ=0.6 warm");
  EXPECT_FALSE(hudHas(s.drawList(1), "diverged"));

  // It stays where it stopped; the other one goes on.
  const long long stopped = bad.world().state().step;
  s.advanceTo(3.0);
  s.step();
  EXPECT_EQ(bad.world().state().step, stopped);
  EXPECT_EQ(good.state().step, 181);
  // reset() gives it a fresh start.
  s.reset();
  EXPECT_FALSE(s.panel(0).diverged());
  EXPECT_EQ(s.panel(0).state().step, 0);
}

// The HUD: a lone panel names the scene and its settings; panels of a grid are labelled with
// theirs instead. The measured step cost (wall-clock) only when asked.
TEST(RenderSession, HudNamesTheSceneOrLabelsThePanels) {
  RenderSession lone(sceneFile("stack.json"), {{settings(Algorithm::A2), ""}});
  lone.advanceTo(0.5);
  DrawList dl = lone.drawList(0);
  ASSERT_EQ(dl.hud.size(), 3u);
  EXPECT_EQ(dl.hud[0].text, "stack: 5 bodies, 0 joints");
  EXPECT_EQ(dl.hud[1].text, settingsLine(settings(Algorithm::A2), LineDetail::Hud));
  EXPECT_EQ(dl.hud[2].text, "t = 0.500 s");
  EXPECT_TRUE(dl.label.empty());
  Look look = lone.look();
  look.stepCost = true;
  lone.setLook(look);
  EXPECT_NE(lone.drawList(0).hud[2].text.find("    step "), std::string::npos) << lone.drawList(0).hud[2].text;

  RenderSession grid(sceneFile("stack.json"), {{settings(Algorithm::A2), "a2"}, {settings(Algorithm::A5), "a5"}});
  const std::vector<DrawList> lists = grid.drawLists();
  ASSERT_EQ(lists.size(), 2u);
  EXPECT_EQ(lists[0].label, "a2 m=10");
  EXPECT_EQ(lists[1].label, "a5 n=4 m=1 κ=1 τ=0.6");
  ASSERT_EQ(lists[1].hud.size(), 1u);
  EXPECT_EQ(lists[1].hud[0].text, "t = 0.000 s");
}

// A panel replaced, or its settings changed, between frames: replaced, it starts over from the
// scene; changed, it goes on from its state under the new settings.
TEST(RenderSession, PanelsAreReplacedOrChangedBetweenFrames) {
  RenderSession s(sceneFile("pendulum_chain.json"), {{settings(Algorithm::A2), "a2"}, {settings(Algorithm::A2), "a2'"}});
  s.advanceTo(0.5);
  s.setPanel(1, {settings(Algorithm::A5), "a5"});
  EXPECT_EQ(s.panel(1).name(), "a5");
  EXPECT_EQ(s.panel(1).settings().algorithm, Algorithm::A5);
  EXPECT_EQ(s.panel(1).state().step, 0);
  EXPECT_EQ(s.panel(0).state().step, 30);
  s.advanceTo(1.0);  // catches up
  EXPECT_EQ(s.panel(1).state().step, 60);

  SolverSettings a4 = settings(Algorithm::A4);
  s.setSettings(0, a4);
  EXPECT_EQ(s.panel(0).settings().algorithm, Algorithm::A4);
  EXPECT_EQ(s.panel(0).setup().settings.algorithm, Algorithm::A4);
  EXPECT_EQ(s.panel(0).state().step, 60);  // no restart
  s.step();
  EXPECT_EQ(s.panel(0).state().step, 61);

  s.setPanels({{settings(Algorithm::A3), ""}});
  EXPECT_EQ(s.panelCount(), 1);
  EXPECT_EQ(s.panel(0).state().step, 0);
  EXPECT_TRUE(s.drawList(0).label.empty());  // a lone panel again
}

// A World that cannot be made is a PanelError naming the panel, and the session keeps what it had.
TEST(RenderSession, AnImpossiblePanelIsAPanelError) {
  Scene bad = *sceneFile("stack.json");
  bad.model.bodies[1].isStatic = false;
  bad.model.bodies[1].shape.type = ShapeType::Plane;  // a moving plane: World refuses it
  try {
    RenderSession s(std::make_shared<const Scene>(bad), {{settings(Algorithm::A2), "a2"}});
    FAIL() << "a dynamic plane must be refused";
  } catch (const PanelError& e) {
    EXPECT_EQ(e.panel, 0);
    EXPECT_NE(std::string(e.what()).find("must be static"), std::string::npos) << e.what();
  }
}

// The camera changes between frames: a new preset, an orbit with simulated time, a followed body.
TEST(RenderSession, TheCameraChangesBetweenFrames) {
  RenderSession s(sceneFile("pendulum_chain.json"), {{settings(Algorithm::A2), ""}});
  const Camera first = s.drawList(0).camera;
  CameraPreset c = s.look().camera;
  c.yaw += 90;
  s.setCamera(c);
  const Camera turned = s.drawList(0).camera;
  EXPECT_GT((turned.eye - first.eye).norm(), 1.0);
  EXPECT_LT((turned.target - first.target).norm(), 1e-6);
  s.setCamera(c, 90);  // 90 degrees per simulated second
  s.advanceTo(1.0);
  const Camera orbited = s.drawList(0).camera;
  EXPECT_GT((orbited.eye - turned.eye).norm(), 1.0);
  c.follow = "pendulum_9";
  s.setCamera(c);
  const Vec3 tip = s.panel(0).state().bodies[static_cast<size_t>(s.scene().model.bodyIndex("pendulum_9"))].x;
  EXPECT_LT((s.drawList(0).camera.target - tip.cast<float>()).norm(), 1e-5);
}

// frame() draws the draw lists into the renderer's frame: the grid's two panels side by side.
TEST(RenderSession, FrameIsTheDrawListsInAGrid) {
  RenderSession s(sceneFile("stack.json"), {{settings(Algorithm::A2), "a2"}, {settings(Algorithm::A5), "a5"}});
  s.advanceTo(0.25);
  GlRenderer r(160, 90);
  const Image img = s.frame(r);
  ASSERT_EQ(img.width, 160);
  const std::vector<DrawList> lists = s.drawLists();
  EXPECT_EQ(img.rgba, r.render(gridViews(lists, 160, 90)).rgba);
  const std::vector<View> views = gridViews(lists, 160, 90);
  ASSERT_EQ(views.size(), 2u);
  EXPECT_EQ(views[1].viewport.x, 80);
  EXPECT_EQ(views[1].list, &lists[1]);
  const uint8_t* border = img.pixel(79, 60);  // the dark column between the panels
  EXPECT_LT(border[0] + border[1] + border[2], 30);
  // render() is draw() and finishFrame(), which may run on another thread.
  RawFrame raw;
  r.draw(views, raw);
  Image finished;
  std::thread([&] { finishFrame(raw, finished); }).join();
  EXPECT_EQ(finished.rgba, img.rgba);
}

// Stepped ahead on its own thread, a session gives the same draw lists, in order, as stepped
// frame by frame; a divergence ends the frames, and the session is the caller's again after stop().
TEST(SessionAhead, SameFramesAsSteppingInTurnAndStopsAtADivergence) {
  const std::vector<double> times = {0.0, 0.1, 0.25, 0.25, 0.5, 1.0};
  RenderSession inTurn(sceneFile("stack.json"), {{settings(Algorithm::A2), ""}});
  RenderSession ahead(sceneFile("stack.json"), {{settings(Algorithm::A2), ""}});
  {
    SessionAhead a(ahead, times, 2);
    for (double t : times) {
      inTurn.advanceTo(t);
      const std::vector<DrawList> expected = inTurn.drawLists();
      const SessionAhead::Frame f = a.next();
      ASSERT_FALSE(f.diverged);
      ASSERT_EQ(f.lists.size(), 1u);
      ASSERT_EQ(f.lists[0].solids.size(), expected[0].solids.size());
      for (size_t i = 0; i < expected[0].solids.size(); ++i)
        EXPECT_EQ(f.lists[0].solids[i].position, expected[0].solids[i].position) << t;
    }
    const SessionAhead::Frame past = a.next();  // past the last frame
    EXPECT_TRUE(past.lists.empty());
    EXPECT_FALSE(past.diverged);
  }
  EXPECT_EQ(ahead.panel(0).state().step, 60);

  RenderSession bad(weldedBeam(), {{settings(Algorithm::A5, true), "a5:warm=on"}});
  SessionAhead a(bad, {0.5, 1.0, 1.5, 2.0, 2.5}, 1);
  int frames = 0;
  for (;;) {
    const SessionAhead::Frame f = a.next();
    if (f.diverged || f.lists.empty()) {
      EXPECT_TRUE(f.diverged);
      break;
    }
    ++frames;
  }
  EXPECT_EQ(frames, 2);  // diverges near t = 1.2 s
  a.stop();
  ASSERT_NE(bad.firstDiverged(), nullptr);
  EXPECT_NE(bad.firstDiverged()->problem().find("diverged"), std::string::npos);
}

// A pixel's ray finds the body drawn there, in the panel under it; a push moves that body in
// every panel, at the same point of it.
TEST(RenderSession, PickFindsTheBodyUnderAPixelAndPushMovesItInEveryPanel) {
  const auto scene = sceneFile("box_on_ground.json");
  Look look;
  look.camera = chooseCamera(*scene, {});
  RenderSession one(scene, {{settings(Algorithm::A2), ""}}, look);
  RenderSession::Pick p = one.pick(320, 180, 160, 90);  // the camera looks at the box
  EXPECT_EQ(p.panel, 0);
  ASSERT_GE(p.hit.body, 0);
  EXPECT_EQ(scene->model.bodies[static_cast<size_t>(p.hit.body)].name, "box");
  EXPECT_NEAR(p.direction.norm(), 1, 1e-9);
  EXPECT_LT((p.origin + p.hit.distance * p.direction - p.hit.point).norm(), 1e-6);
  EXPECT_EQ(one.pick(320, 180, 2, 2).hit.body, -1);  // sky

  RenderSession two(scene, {{settings(Algorithm::A2), "a2"}, {settings(Algorithm::A5), "a5"}}, look);
  p = two.pick(320, 180, 240, 90);  // the right half: panel 1's centre
  EXPECT_EQ(p.panel, 1);
  ASSERT_GE(p.hit.body, 0);
  two.push(p.panel, p.hit.body, Vec3(3, 0, 0), p.hit.point);
  two.step();
  for (int i = 0; i < 2; ++i) EXPECT_GT(two.panel(i).state().bodies[static_cast<size_t>(p.hit.body)].v.x(), 1) << i;
  EXPECT_THROW(two.push(0, 0, Vec3(0, 1, 0), Vec3::Zero()), std::invalid_argument);  // the ground is static
}

// Another scene replaces the panels at once; a scene whose settings fail changes nothing.
TEST(RenderSession, SetSceneReplacesSceneAndPanels) {
  RenderSession s(sceneFile("stack.json"), {{settings(Algorithm::A2), ""}});
  s.advanceTo(0.5);
  s.setScene(sceneFile("chain.json"), {{settings(Algorithm::A5), "a"}, {settings(Algorithm::A2), "b"}});
  EXPECT_EQ(s.panelCount(), 2);
  EXPECT_EQ(s.panel(0).state().time, 0);
  EXPECT_EQ(s.scene().model.joints.size(), 30u);
  Scene bad = *sceneFile("stack.json");
  bad.model.bodies[1].isStatic = false;
  bad.model.bodies[1].shape.type = ShapeType::Plane;  // World refuses it
  EXPECT_THROW(s.setScene(std::make_shared<const Scene>(bad), {{settings(Algorithm::A2), ""}}), PanelError);
  EXPECT_EQ(s.panelCount(), 2);
  EXPECT_EQ(s.scene().model.joints.size(), 30u);
}

namespace {

bool sameBits(const State& a, const State& b) {
  if (a.step != b.step || a.time != b.time || a.bodies.size() != b.bodies.size()) return false;
  // Field by field: a BodyState has padding.
  auto same = [](const double* x, const double* y, size_t n) { return std::memcmp(x, y, n * sizeof(double)) == 0; };
  for (size_t i = 0; i < a.bodies.size(); ++i) {
    const BodyState &p = a.bodies[i], &q = b.bodies[i];
    if (!same(p.x.data(), q.x.data(), 3) || !same(p.q.coeffs().data(), q.q.coeffs().data(), 4) ||
        !same(p.v.data(), q.v.data(), 3) || !same(p.w.data(), q.w.data(), 3))
      return false;
  }
  return true;
}

// The states of an uninterrupted run of the scene, from step 0.
std::vector<State> trajectory(const Scene& scene, const SolverSettings& s, int steps) {
  World w(scene.model, s, scene.initial);
  std::vector<State> out{w.state()};
  for (int k = 0; k < steps; ++k) {
    w.step();
    out.push_back(w.state());
  }
  return out;
}

}  // namespace

// The timeline: a kept step is shown as it was (bit for bit), without stepping again; going back and
// forth never changes the world.
TEST(RenderSession, ScrubbingShowsKeptStepsWithoutSteppingAgain) {
  const auto scene = sceneFile("ragdoll_pile.json");
  const SolverSettings a5 = settings(Algorithm::A5);
  const std::vector<State> ref = trajectory(*scene, a5, 90);
  RenderSession s(scene, {{a5, ""}});
  s.setHistoryLimits({60, size_t{1} << 30});
  s.advanceTo(90 / 60.0);
  ASSERT_EQ(s.panel(0).steps(), 90);
  EXPECT_TRUE(s.live());
  s.view(0.5);
  EXPECT_FALSE(s.live());
  EXPECT_EQ(s.panel(0).state().step, 30);
  EXPECT_TRUE(sameBits(s.panel(0).state(), ref[30]));
  s.viewBy(-7);
  EXPECT_TRUE(sameBits(s.panel(0).state(), ref[23]));
  s.viewBy(2);
  EXPECT_TRUE(sameBits(s.panel(0).state(), ref[25]));
  s.view(-5);  // before the first: the first
  EXPECT_TRUE(sameBits(s.panel(0).state(), ref[0]));
  EXPECT_EQ(s.panel(0).steps(), 90);  // nothing stepped again
  EXPECT_TRUE(sameBits(s.panel(0).world().state(), ref[90]));
  // Contacts of a past step are the ones of that step.
  s.view(1.0);
  EXPECT_EQ(s.panel(0).shown().state.step, 60);
  s.viewLive();
  EXPECT_TRUE(s.live());
  EXPECT_TRUE(sameBits(s.panel(0).state(), ref[90]));
}

// Play resumed from a step scrubbed back to goes through the kept steps, then steps on: the same
// trajectory as a run that never went back.
TEST(RenderSession, ResumingFromAPastStepGivesTheUninterruptedTrajectory) {
  const auto scene = sceneFile("ragdoll_pile.json");
  const SolverSettings a5 = settings(Algorithm::A5);
  const std::vector<State> ref = trajectory(*scene, a5, 150);
  RenderSession s(scene, {{a5, ""}, {settings(Algorithm::A2), "a2"}});
  s.setHistoryLimits({60, size_t{1} << 30});
  s.advanceTo(1.0);
  s.view(0.25);
  s.step();  // one step forward in the past: the kept step 16
  EXPECT_TRUE(sameBits(s.panel(0).state(), ref[16]));
  EXPECT_EQ(s.panel(0).steps(), 60);
  s.advanceTo(150 / 60.0);
  EXPECT_TRUE(s.live());
  EXPECT_EQ(s.panel(0).steps(), 150);
  for (int k : {40, 60, 61, 100, 150}) {
    s.view(k / 60.0);
    EXPECT_TRUE(sameBits(s.panel(0).state(), ref[static_cast<size_t>(k)])) << "step " << k;
  }
}

// The past cannot be changed: a push or a settings change while it is shown is refused and says how
// to go on; at the newest step both work.
TEST(RenderSession, ThePastRefusesChanges) {
  RenderSession s(sceneFile("stack.json"), {{settings(Algorithm::A2), ""}});
  s.setHistoryLimits({60, size_t{1} << 30});
  s.advanceTo(0.5);
  s.view(0.25);
  const int top = static_cast<int>(s.scene().model.bodies.size()) - 1;
  try {
    s.push(0, top, Vec3(1, 0, 0), s.panel(0).state().bodies[static_cast<size_t>(top)].x);
    FAIL() << "a push in the past went through";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("go live first"), std::string::npos) << e.what();
  }
  EXPECT_THROW(s.setSettings(0, settings(Algorithm::A3)), std::invalid_argument);
  s.viewLive();
  s.push(0, top, Vec3(1, 0, 0), s.panel(0).state().bodies[static_cast<size_t>(top)].x);
  s.setSettings(0, settings(Algorithm::A3));
}

// The history keeps the last seconds asked for (and the newest step whatever it costs); a session
// with no history asked for keeps the newest only.
TEST(RenderSession, HistoryKeepsTheLastSecondsAskedFor) {
  RenderSession s(sceneFile("stack.json"), {{settings(Algorithm::A2), ""}});
  s.advanceTo(1.0);
  EXPECT_EQ(s.panel(0).history().size(), 1u);
  s.setHistoryLimits({0.5, size_t{1} << 30});
  s.advanceTo(2.0);
  EXPECT_NEAR(s.firstKept(), 1.5, 1e-9);
  EXPECT_NEAR(s.lastKept(), 2.0, 1e-9);
  EXPECT_EQ(s.panel(0).history().size(), 31u);
  s.view(0.2);  // older than kept: the oldest kept
  EXPECT_NEAR(s.time(), 1.5, 1e-9);
  s.setHistoryLimits({60, 1});  // one byte: the newest only
  EXPECT_EQ(s.panel(0).history().size(), 1u);
  EXPECT_TRUE(s.live());
}

// A recorded session shows its frames and never steps: it ends at its last frame; the snapshot hook
// sees every frame once.
TEST(RenderSession, ARecordedSessionReplaysItsFramesAndEnds) {
  const auto scene = sceneFile("stack.json");
  const SolverSettings a2 = settings(Algorithm::A2);
  const std::vector<State> ref = trajectory(*scene, a2, 40);
  std::vector<Snapshot> frames;
  for (size_t k = 0; k < ref.size(); k += 4) frames.push_back(takeSnapshot(scene->model, ref[k]));
  RenderSession s(scene, {{a2, ""}});
  int hooked = 0;
  s.setSnapshotHook([&](int panel, const std::shared_ptr<const Scene>&, const Snapshot&) { hooked += panel == 0; });
  const int before = hooked;
  s.setRecorded(scene, {{a2, ""}}, {frames});
  EXPECT_EQ(hooked - before, static_cast<int>(frames.size()));
  EXPECT_TRUE(s.recorded());
  EXPECT_EQ(s.time(), 0);
  s.advanceTo(0.3);  // step 18: the frame of step 16
  EXPECT_TRUE(sameBits(s.panel(0).state(), ref[16]));
  s.advanceTo(10);
  EXPECT_TRUE(sameBits(s.panel(0).state(), ref[40]));
  EXPECT_TRUE(s.ended());
  EXPECT_EQ(s.panel(0).steps(), 0);
  EXPECT_EQ(s.panel(0).world().state().step, 0);
  EXPECT_THROW(s.push(0, 1, Vec3(1, 0, 0), Vec3::Zero()), std::invalid_argument);
  s.viewBy(-1);
  EXPECT_TRUE(sameBits(s.panel(0).state(), ref[36]));
}
