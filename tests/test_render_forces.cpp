// Force and joint-error overlays drawn by OSMesa: contact impulses as arrows at the contact points,
// their length following the scale, joint separations as red segments, and the legend. The
// frames are written to <build>/test_render_out/forces/ to be looked at.
#include "physics/scene_file.h"
#include "physics/world.h"
#include "render/gl_renderer.h"
#include "render/image.h"
#include "render/scene_builder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>

namespace fs = std::filesystem;
using namespace substep;
using namespace substep::render;

namespace {

constexpr int kWidth = 480, kHeight = 270;

Scene scene(const std::string& name) { return loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/" + name); }

GlRenderer& renderer() {
  static std::unique_ptr<GlRenderer> r;
  if (!r) r = std::make_unique<GlRenderer>(kWidth, kHeight);
  return *r;
}

Image draw(const DrawList& dl, const std::string& name) {
  const Image img = renderer().render(dl);
  const fs::path d = fs::path(SUBSTEP_BINARY_DIR) / "test_render_out" / "forces";
  fs::create_directories(d);
  writePng((d / (name + ".png")).string(), img);
  return img;
}

// Where a world point lands in the frame [pixels, row 0 at the top].
Eigen::Vector2f toPixel(const Camera& c, const Vec3f& p) {
  const Eigen::Vector4f h = c.projection(float(kWidth) / kHeight) * c.view() * Eigen::Vector4f(p.x(), p.y(), p.z(), 1);
  return {(h.x() / h.w() * 0.5f + 0.5f) * kWidth, (0.5f - h.y() / h.w() * 0.5f) * kHeight};
}

bool differs(const Image& a, const Image& b, int x, int y) {
  const uint8_t *p = a.pixel(x, y), *q = b.pixel(x, y);
  for (int k = 0; k < 3; ++k)
    if (std::abs(int(p[k]) - int(q[k])) > 24) return true;
  return false;
}

long long count(const Image& img, const std::function<bool(int, int, const uint8_t*)>& f) {
  long long n = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) n += f(x, y, img.pixel(x, y));
  return n;
}

// The arrow colours as the flat overlay shades them (0.55 to 1 of the colour): far from the
// blue-grey of resting bodies in Activity colours and from the grey ground.
bool orange(const uint8_t* p) { return p[0] > 120 && p[2] < 0.35 * p[0] && p[1] > 0.35 * p[0] && p[1] < 0.75 * p[0]; }
bool red(const uint8_t* p) { return p[0] > 120 && p[1] < 0.3 * p[0] && p[2] < 0.3 * p[0]; }

// The stack at rest after a second of steps: its contacts carry the boxes' weight.
struct RestingStack {
  Scene s = scene("stack.json");
  World world{s.model, resolve(s.solver), s.initial};
  Snapshot snap;
  Camera cam;
  RestingStack() {
    for (int i = 0; i < 60; ++i) world.step();
    snap = takeSnapshot(world);
    CameraPreset p = chooseCamera(s, {});
    p.distance = 9;
    p.target = Vec3(0, 2.5, 0);
    cam = placeCamera(p, s.model, snap.state);
  }
  ViewOptions view(bool forces, double scale = 0) const {
    ViewOptions v;
    v.colour = ColourMode::Activity;  // bodies blue-grey at rest: the arrows' colours stand out
    v.hud = false;
    v.forces = forces;
    v.forceScale = scale;
    v.impulseTime = impulseTime(world.settings());
    return v;
  }
};

}  // namespace

// The automatic scale: the heaviest body's weight over the impulses' time drawn as long as its
// bounding radius, rounded down to 1, 2 or 5 times a power of ten; the legend reads it back.
TEST(ForceOverlay, AutomaticScaleFollowsTheHeaviestBodyAndTheImpulseTime) {
  const Scene s = scene("stack.json");  // 1 kg unit boxes: radius √3/2 m, m g h = 0.1635 N s at h = 1/60 s
  const Snapshot snap = takeSnapshot(s.model, s.initial);
  EXPECT_DOUBLE_EQ(autoForceScale(s.model, snap, 1.0 / 60), 5.0);   // 5.30 rounded down
  EXPECT_DOUBLE_EQ(autoForceScale(s.model, snap, 1.0 / 240), 20.0);  // four sub-steps: 21.2
  EXPECT_DOUBLE_EQ(autoForceScale(s.model, snap), 5.0);              // no time given, t = 0: 1/60 s
  SolverSettings a5 = resolve(s.solver);
  a5.algorithm = Algorithm::A5;
  a5.substeps = 4;
  EXPECT_DOUBLE_EQ(impulseTime(a5), a5.dt / 4);
  EXPECT_DOUBLE_EQ(impulseTime(resolve(s.solver)), resolve(s.solver).dt);
  EXPECT_EQ(forceLegend(5.0, 0.6), "arrow 50 cm = 0.1 N s");
  EXPECT_EQ(forceLegend(20.0, 0.05), "arrow 5 cm = 0.0025 N s");
  EXPECT_EQ(forceLegend(0.2, 3.0), "arrow 2 m = 10 N s");
}

// Forces on: the frame changes around the contact points that carry weight (each arrow starts
// at its point), and the draw list has an arrow (shaft and cone head) per loaded contact.
TEST(ForceOverlay, ArrowsAppearAtTheContactPoints) {
  const RestingStack st;
  int loaded = 0;
  for (const ContactSnap& c : st.snap.contacts) loaded += c.normalImpulse > 0;
  ASSERT_GE(loaded, 16);  // four points under each of five boxes, most of them pressed
  const DrawList off = buildDrawList(st.s.model, st.snap, st.cam, st.view(false), {});
  const DrawList on = buildDrawList(st.s.model, st.snap, st.cam, st.view(true), {});
  EXPECT_TRUE(off.overlays.empty());
  int heads = 0;
  for (const Instance& in : on.overlays) heads += in.mesh == kConeMesh;
  EXPECT_GE(heads, loaded);  // one per normal impulse, one per manifold's friction (when not zero)
  const Image a = draw(off, "stack_off"), b = draw(on, "stack_on");
  long long near = 0, total = 0;
  for (const ContactSnap& c : st.snap.contacts) {
    if (!(c.normalImpulse > 0)) continue;
    const Eigen::Vector2f p = toPixel(st.cam, c.point);
    for (int y = int(p.y()) - 4; y <= int(p.y()) + 4; ++y)
      for (int x = int(p.x()) - 4; x <= int(p.x()) + 4; ++x)
        if (x >= 0 && y >= 0 && x < kWidth && y < kHeight) near += differs(a, b, x, y);
  }
  total = count(a, [&](int x, int y, const uint8_t*) { return differs(a, b, x, y); });
  EXPECT_GT(near, 4 * loaded) << "changed pixels near the contact points";
  EXPECT_GT(total, 300);
  EXPECT_GT(count(b, [](int, int, const uint8_t* p) { return orange(p); }), 200);
  EXPECT_LT(count(a, [](int, int, const uint8_t* p) { return orange(p); }), 10);  // the colour is the arrows'
}

// Twice the scale, longer arrows: more pixels of the arrows' colour and a taller extent (the
// arrows point up from the boxes' faces).
TEST(ForceOverlay, DoublingTheScaleLengthensTheArrows) {
  const RestingStack st;
  const double k = autoForceScale(st.s.model, st.snap, impulseTime(st.world.settings()));
  const Image one = draw(buildDrawList(st.s.model, st.snap, st.cam, st.view(true, k), {}), "stack_scale1");
  const Image two = draw(buildDrawList(st.s.model, st.snap, st.cam, st.view(true, 2 * k), {}), "stack_scale2");
  auto extent = [](const Image& img, long long& n) {
    int top = img.height, bottom = -1;
    n = 0;
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x)
        if (orange(img.pixel(x, y))) {
          ++n;
          top = std::min(top, y);
          bottom = std::max(bottom, y);
        }
    return bottom - top;
  };
  long long n1 = 0, n2 = 0;
  const int e1 = extent(one, n1), e2 = extent(two, n2);
  EXPECT_GT(n1, 100);
  EXPECT_GT(n2, 1.4 * n1) << n1 << " orange pixels at scale " << k << ", " << n2 << " at twice";
  EXPECT_GT(e2, e1) << "the topmost arrow reaches higher";
}

// Joint errors: none drawn for a chain whose joints hold; a link moved 25 cm shows a red segment
// from its joint's anchor on one body to the anchor on the other, and only there.
TEST(JointErrorOverlay, ARedSegmentJoinsSeparatedAnchors) {
  const Scene s = scene("pendulum_chain.json");
  ViewOptions v;
  v.colour = ColourMode::Activity;
  v.hud = false;
  v.jointErrors = true;
  CameraPreset p = chooseCamera(s, {});
  p.distance = 3;
  p.target = Vec3(1.2, 6, 0);
  const Camera cam = placeCamera(p, s.model, s.initial);
  const DrawList held = buildDrawList(s.model, takeSnapshot(s.model, s.initial), cam, v, {});
  EXPECT_TRUE(held.overlays.empty());
  EXPECT_EQ(count(draw(held, "chain_held"), [](int, int, const uint8_t* q) { return red(q); }), 0);

  State moved = s.initial;
  const int link = s.model.bodyIndex("pendulum_2");
  ASSERT_GE(link, 0);
  moved.bodies[static_cast<size_t>(link)].x += Vec3(0, 0.25, 0);
  const Snapshot snap = takeSnapshot(s.model, moved);
  ASSERT_GT(snap.worstJointError(), 0.24);
  const DrawList broken = buildDrawList(s.model, snap, cam, v, {});
  EXPECT_EQ(broken.overlays.size(), 2u);  // the link's joints to either neighbour
  const Image img = draw(broken, "chain_moved");
  // Every red pixel lies near one of the separated joints' segments, and there are many.
  std::vector<std::pair<Eigen::Vector2f, Eigen::Vector2f>> segments;
  for (const Joint& j : s.model.joints) {
    if (j.bodyA != link && j.bodyB != link) continue;
    segments.push_back({toPixel(cam, moved.bodies[static_cast<size_t>(j.bodyA)].pose().apply(j.localAnchorA).cast<float>()),
                        toPixel(cam, moved.bodies[static_cast<size_t>(j.bodyB)].pose().apply(j.localAnchorB).cast<float>())});
  }
  ASSERT_EQ(segments.size(), 2u);
  auto distance = [](const Eigen::Vector2f& q, const Eigen::Vector2f& a, const Eigen::Vector2f& b) {
    const Eigen::Vector2f d = b - a;
    const float t = std::clamp((q - a).dot(d) / std::max(d.squaredNorm(), 1e-6f), 0.0f, 1.0f);
    return (a + t * d - q).norm();
  };
  long long onSegment = 0, elsewhere = 0;
  count(img, [&](int x, int y, const uint8_t* q) {
    if (!red(q)) return false;
    const Eigen::Vector2f c(x + 0.5f, y + 0.5f);
    float best = 1e9f;
    for (const auto& [a, b] : segments) best = std::min(best, distance(c, a, b));
    (best < 6 ? onSegment : elsewhere) += 1;
    return true;
  });
  const float length = (segments[0].second - segments[0].first).norm();
  EXPECT_GT(length, 20);  // pixels: the 25 cm seen from 3 m
  EXPECT_GT(onSegment, 2 * length);  // both segments, over a pixel wide
  EXPECT_EQ(elsewhere, 0);
}

// The legend says the scale and the colours, and is drawn: the footer's corner changes.
TEST(ForceOverlay, LegendGivesTheScaleAndTheColours) {
  const RestingStack st;
  ViewOptions v = st.view(true, 5.0);
  v.colour = ColourMode::Auto;  // no colour legend: the footer is the overlays'
  v.hud = true;
  v.jointErrors = true;
  const DrawList dl = buildDrawList(st.s.model, st.snap, st.cam, v, {});
  ASSERT_EQ(dl.footer.size(), 4u);
  EXPECT_NE(dl.footer[0].text.find(" = "), std::string::npos) << dl.footer[0].text;
  EXPECT_NE(dl.footer[0].text.find(" N s"), std::string::npos) << dl.footer[0].text;
  EXPECT_TRUE(dl.footer[1].colour.head<3>().isApprox(normalImpulseColour()));
  EXPECT_TRUE(dl.footer[2].colour.head<3>().isApprox(frictionImpulseColour()));
  EXPECT_TRUE(dl.footer[3].colour.head<3>().isApprox(jointErrorColour()));
  // The stated arrow stands for what the scale says: length = impulse × scale.
  double length = 0, impulse = 0;
  char unit[8] = {};
  ASSERT_EQ(std::sscanf(dl.footer[0].text.c_str(), "impulses: arrow %lf %7s = %lf N s", &length, unit, &impulse), 3)
      << dl.footer[0].text;
  const double metres = length * (std::string(unit) == "cm" ? 0.01 : std::string(unit) == "mm" ? 0.001 : 1.0);
  EXPECT_NEAR(metres, impulse * 5.0, 1e-9 * metres);

  ViewOptions quiet = v;
  quiet.forces = quiet.jointErrors = false;
  const Image with = draw(dl, "stack_legend");
  const Image without = draw(buildDrawList(st.s.model, st.snap, st.cam, quiet, {}), "stack_nolegend");
  long long corner = 0;
  for (int y = kHeight * 3 / 4; y < kHeight; ++y)
    for (int x = 0; x < kWidth / 3; ++x) corner += differs(with, without, x, y);
  EXPECT_GT(corner, 500);
}
