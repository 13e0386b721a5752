// The live session (render/live_session.h), the server's unit without HTTP: a render session
// played on threads of its own, frames drawn only while watched, single steps and seeks, a
// divergence that pauses it, and the gate that gives sessions their turns in order.
#include "physics/scene_file.h"
#include "render/live_session.h"

#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <memory>
#include <stdexcept>
#include <thread>

using namespace substep;
using namespace substep::render;

namespace {

LiveConfig smallConfig() {
  LiveConfig c;
  c.width = 160;
  c.height = 96;
  c.fps = 20;
  return c;
}

std::unique_ptr<LiveSession> live(const std::string& scene, std::shared_ptr<FairGate> drawGate = nullptr,
                                  LiveConfig c = smallConfig()) {
  auto s = std::make_shared<const Scene>(loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/" + scene));
  Look look;
  look.camera = chooseCamera(*s, {});
  c.drawGate = std::move(drawGate);
  return std::make_unique<LiveSession>(s, std::vector<PanelSetup>{{resolve(s->solver), ""}}, look, c);
}

// Waits up to 60 s (a sanitizer build on a busy machine) for the stats to satisfy `ok`.
LiveStats waitFor(const LiveSession& s, const std::function<bool(const LiveStats&)>& ok) {
  LiveStats st = s.stats();
  for (int i = 0; i < 600 && !ok(st); ++i) st = s.waitStats(st.seq, 0.1);
  return st;
}

}  // namespace

TEST(LiveSession, StepsAndSeeksWhilePaused) {
  auto s = live("stack.json");
  EXPECT_FALSE(s->playing());
  ASSERT_EQ(s->stats().panels.size(), 1u);  // stats from the start
  EXPECT_NEAR(s->step(3), 3.0 / 60, 1e-12);
  EXPECT_EQ(s->stats().panels[0].steps, 3);  // published with the change
  s->seek(1.0);
  LiveStats st = waitFor(*s, [](const LiveStats& x) { return !x.seeking && x.panels[0].time > 0.9; });
  EXPECT_NEAR(st.panels[0].time, 1.0, 1e-9);
  EXPECT_FALSE(st.playing);
  s->seek(0.25);  // back: from the start
  st = waitFor(*s, [](const LiveStats& x) { return !x.seeking && x.panels[0].time < 0.9; });
  EXPECT_NEAR(st.panels[0].time, 0.25, 1.0 / 120);
  s->reset();
  EXPECT_EQ(s->stats().panels[0].time, 0);
}

TEST(LiveSession, DrawsOnlyWhileWatched) {
  auto s = live("stack.json");
  s->play(1.0);
  waitFor(*s, [](const LiveStats& x) { return x.panels[0].time > 0.2; });
  EXPECT_EQ(s->stats().frames, 0);  // nobody watched
  {
    LiveSession::Viewer v(*s);
    const LiveFrame f = s->waitFrame(0, 60);
    ASSERT_GT(f.seq, 0);
    ASSERT_GE(f.jpeg->size(), 4u);
    EXPECT_EQ(static_cast<unsigned char>((*f.jpeg)[0]), 0xFF);  // a JPEG's start of image
    EXPECT_EQ(static_cast<unsigned char>((*f.jpeg)[1]), 0xD8);
    const Image img = decodeImage(f.jpeg->data(), f.jpeg->size());
    EXPECT_EQ(img.width, 160);
    EXPECT_EQ(img.height, 96);
    EXPECT_GT(s->waitFrame(f.seq, 60).seq, f.seq);  // it plays: the next one comes
  }
  s->pause();
  const auto png = s->image(60);
  ASSERT_TRUE(png);
  EXPECT_EQ(png->width, 160);
  EXPECT_THROW(s->record("sideways", 1), std::invalid_argument);
}

TEST(LiveSession, ADivergencePausesAndSaysWhy) {
  auto s = live("box_on_ground.json");
  s->change([](RenderSession& r, Look&) { r.push(0, 1, Vec3(1e9, 0, 0), r.panel(0).state().bodies[1].x); });
  s->play(1.0);
  const LiveStats st = waitFor(*s, [](const LiveStats& x) { return x.panels[0].diverged && !x.playing; });
  EXPECT_TRUE(st.panels[0].diverged);
  EXPECT_FALSE(st.playing);
  EXPECT_NE(st.status.find("diverged"), std::string::npos) << st.status;
  // A restart that is refused (other panels that cannot be made) leaves the session as it was.
  EXPECT_THROW(s->restart([](RenderSession&, Look&) { throw std::invalid_argument("refused"); }), std::invalid_argument);
  EXPECT_NE(s->stats().status.find("diverged"), std::string::npos);
  s->reset();
  EXPECT_EQ(s->stats().status, "");
  EXPECT_FALSE(s->stats().panels[0].diverged);
}

// A tick that comes late (here: its draw waits a second for its turn) makes up for 0.25 s only,
// and the stats say the session fell behind.
TEST(LiveSession, ALateTickFallsBehindAndSaysSo) {
  auto gate = std::make_shared<FairGate>(1);
  auto s = live("stack.json", gate);
  s->play(1.0);
  LiveSession::Viewer v(*s);
  ASSERT_GT(s->waitFrame(0, 60).seq, 0);
  {
    FairGate::Turn hold(gate.get());  // the next draw waits
    std::this_thread::sleep_for(std::chrono::seconds(1));
  }
  const LiveStats st = waitFor(*s, [](const LiveStats& x) { return x.behind; });
  EXPECT_TRUE(st.behind);
  EXPECT_LT(st.achieved, 0.95);
}

// Asked for more frames than its drawing allows (720p at 200 fps: 5 ms a frame, where this
// machine draws the pyramid in 12 ms or more), a session draws smaller and says why; told to keep
// its size, it does, and is slow.
TEST(LiveSession, DrawsSmallerWhenTheDrawingCannotKeepTheRate) {
  LiveConfig c;
  c.fps = 200;
  auto s = live("pyramid.json", nullptr, c);
  s->play(1.0);
  LiveSession::Viewer v(*s);
  const LiveStats st = waitFor(*s, [](const LiveStats& x) { return x.width < 1280; });
  ASSERT_LT(st.width, 1280) << "draw " << st.drawMs << " ms";
  EXPECT_EQ(st.width * 720, st.height * 1280);  // the same shape
  EXPECT_NE(st.sizeNote.find("drawn at " + std::to_string(st.width) + "x" + std::to_string(st.height) + " of 1280x720"),
            std::string::npos)
      << st.sizeNote;
  EXPECT_NE(st.sizeNote.find("below the 200 fps asked"), std::string::npos) << st.sizeNote;
  // The frames now come at that size.
  LiveFrame f = s->waitFrame(0, 60);
  for (int k = 0; k < 100; ++k) {
    const Image img = decodeImage(f.jpeg->data(), f.jpeg->size());
    if (img.width < 1280) {
      EXPECT_LT(img.height, 720);
      break;
    }
    f = s->waitFrame(f.seq, 60);
    ASSERT_LT(k, 99) << "no frame drawn smaller";
  }

  c.adaptSize = false;
  auto fixed = live("pyramid.json", nullptr, c);
  fixed->play(1.0);
  LiveSession::Viewer w(*fixed);
  std::this_thread::sleep_for(std::chrono::seconds(4));  // twice what the other took to shrink
  const LiveStats slow = fixed->stats();
  EXPECT_GT(slow.frames, 10);
  EXPECT_EQ(slow.width, 1280);
  EXPECT_EQ(slow.height, 720);
  EXPECT_EQ(slow.sizeNote, "");
  EXPECT_GT(slow.drawMs, 0);
}

// Turns go in the order they were asked for, `slots` at a time.
TEST(FairGate, TurnsInTheOrderAsked) {
  FairGate gate(1);
  std::vector<int> order;
  std::mutex m;
  std::vector<std::thread> threads;
  {
    FairGate::Turn first(&gate);
    for (int k = 0; k < 4; ++k) {
      threads.emplace_back([&, k] {
        FairGate::Turn t(&gate);
        std::lock_guard<std::mutex> lk(m);
        order.push_back(k);
      });
      while (gate.waiting() < k + 1) std::this_thread::yield();  // k is in the queue before k + 1 asks
    }
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(gate.waiting(), 0);
}
