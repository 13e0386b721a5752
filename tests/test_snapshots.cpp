// Snapshot image tests: fixed scenes at fixed times drawn by OSMesa and compared with the golden
// PNGs in tests/snapshots/, with a tolerance that absorbs llvmpipe's rounding but not a moved body.
//
//   a mismatch   writes <build>/snapshots/<name>.actual.png and <name>.diff.png and names them
//   update       SUBSTEP_UPDATE_SNAPSHOTS=1 ctest -R Snapshot   (or run the test binary) rewrites the goldens
//
// Adding a golden is one line in kSnapshots and an update run.
#include "physics/scene_file.h"
#include "physics/world.h"
#include "render/compare.h"
#include "render/gl_renderer.h"
#include "render/image.h"
#include "render/scene_builder.h"
#include "render/session.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>

namespace fs = std::filesystem;
using namespace substep;
using namespace substep::render;

namespace {

// Per-pixel threshold and largest share of differing pixels (26 of 129600 at 480x270): the
// defaults, which `substep snapshot` uses too. Measured: two renders on this machine are
// identical; moving the top box of the stack by 2 cm (about 0.6 px) changes 80 pixels by more
// than the threshold (see ComparisonCanFail).
const CompareOptions kTolerance;

struct Golden {
  std::string name;      // tests/snapshots/<name>.png
  std::string scene;     // under assets/scenes/
  double time;           // simulated seconds
  std::string compare;   // --compare syntax for a grid, empty for one view
  std::function<void(ViewOptions&, CameraOptions&)> setup = nullptr;
  int width = 480, height = 270;
};

// The library of goldens (adding one: a line here, then an update run, then look at the image).
const std::vector<Golden> kSnapshots = {
    // The basic resting stack, lit and shadowed, with the HUD.
    {"stack", "stack.json", 1.0, "",
     [](ViewOptions&, CameraOptions& c) {
       c.distance = 10;
       c.target = Vec3(0, 3.0, 0);  // the whole stack below the HUD
     }},
    // A ragdoll come to rest on the steps, with its joints drawn.
    {"ragdoll_pose", "ragdoll.json", 1.0, "",
     [](ViewOptions& v, CameraOptions& c) {
       v.joints = true;
       c.distance = 2.6;
       c.target = Vec3(0.2, 0.8, 0.6);
       c.yaw = 60;
       c.pitch = 25;
     }},
    // Every primitive and both mesh kinds, with contact points and normals.
    {"shapes_contacts", "shapes.json", 1.5, "",
     [](ViewOptions& v, CameraOptions& c) {
       v.contacts = true;
       c.distance = 7;
     }},
    // The comparison: PGS with 4 iterations stretches the ragdoll's joints, A5 holds them.
    {"compare_grid", "ragdoll.json", 1.0, "a2:m=4,a5:n=4",
     [](ViewOptions& v, CameraOptions& c) {
       v.colour = ColourMode::Error;
       v.errorScale = 0.02;
       c.distance = 2.6;
       c.target = Vec3(0.2, 0.8, 0.6);
       c.yaw = 60;
       c.pitch = 25;
     }},
    // The pendulum chain mid-swing, coloured by speed: slow at the anchor, fast at the tip.
    {"chain_speed", "pendulum_chain.json", 0.6, "",
     [](ViewOptions& v, CameraOptions& c) {
       v.colour = ColourMode::Speed;
       v.speedScale = 8;
       c.distance = 8;
       c.target = Vec3(2.6, 5.0, 0);
     }},
};

// Test names show the case, not its bytes.
void PrintTo(const Golden& s, std::ostream* os) { *os << s.name; }

std::string goldenPath(const std::string& name) { return SUBSTEP_SOURCE_DIR "/tests/snapshots/" + name + ".png"; }

bool updating() {
  const char* u = std::getenv("SUBSTEP_UPDATE_SNAPSHOTS");
  return u && std::string(u) == "1";
}

// One renderer per frame size for the whole run: a context costs more than a frame.
GlRenderer& renderer(int w, int h) {
  static std::map<std::pair<int, int>, std::unique_ptr<GlRenderer>> cache;
  auto& r = cache[{w, h}];
  if (!r) r = std::make_unique<GlRenderer>(w, h);
  return *r;
}

// The case's session, stepped to its time: the session `substep render` and `substep snapshot` use.
RenderSession stage(const Golden& s) {
  auto scene = std::make_shared<const Scene>(loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/" + s.scene));
  Look look;  // stepCost off: the HUD leaves out the step's cost (wall-clock time is not reproducible)
  CameraOptions cam;
  if (s.setup) s.setup(look.view, cam);
  look.camera = chooseCamera(*scene, cam);
  const std::vector<CompareSpec> specs = s.compare.empty() ? std::vector<CompareSpec>(1) : parseCompareSpecs(s.compare);
  std::vector<PanelSetup> panels;
  for (const CompareSpec& c : specs) panels.push_back({resolve(scene->solver.withCommandLine(c.overrides)), c.text});
  RenderSession session(scene, panels, look);
  session.advanceTo(s.time);
  if (const Panel* p = session.firstDiverged()) throw std::runtime_error(s.name + ": " + p->problem());
  return session;
}

Image draw(const Golden& s, const std::vector<DrawList>& lists) {
  return renderer(s.width, s.height).render(gridViews(lists, s.width, s.height));
}

fs::path failureDir() {
  const fs::path d = fs::path(SUBSTEP_BINARY_DIR) / "snapshots";
  fs::create_directories(d);
  return d;
}

class Snapshots : public ::testing::TestWithParam<Golden> {};

}  // namespace

TEST_P(Snapshots, MatchesTheGolden) {
  const Golden& s = GetParam();
  const Image actual = stage(s).frame(renderer(s.width, s.height));
  const std::string golden = goldenPath(s.name);
  if (updating()) {
    writePng(golden, actual);
    std::cout << "updated " << golden << "\n";
    return;
  }
  ASSERT_TRUE(fs::exists(golden)) << "no golden image " << golden
                                  << "; create it with SUBSTEP_UPDATE_SNAPSHOTS=1 and look at it before committing";
  const CompareResult r = compareImages(readPng(golden), actual, kTolerance);
  if (!r.match) {
    const fs::path a = failureDir() / (s.name + ".actual.png"), d = failureDir() / (s.name + ".diff.png");
    writePng(a.string(), actual);
    if (r.sameSize) writePng(d.string(), r.diff);
    FAIL() << s.name << ": " << r.summary() << " (tolerance: channel difference over " << kTolerance.threshold
           << " on at most " << kTolerance.maxShare * 100 << "% of pixels)\n  golden: " << golden
           << "\n  actual: " << a.string() << (r.sameSize ? "\n  diff:   " + d.string() : std::string())
           << "\n  if the change is intended: SUBSTEP_UPDATE_SNAPSHOTS=1 " << ::testing::internal::GetArgvs()[0];
  }
}

INSTANTIATE_TEST_SUITE_P(Golden, Snapshots, ::testing::ValuesIn(kSnapshots),
                         [](const ::testing::TestParamInfo<Golden>& i) { return i.param.name; });

// The comparison must be able to fail: the stack with its top box moved 2 cm sideways does not
// match the stack as it is.
TEST(SnapshotTolerance, ComparisonCanFail) {
  const Golden& s = kSnapshots[0];
  ASSERT_EQ(s.name, "stack");
  const RenderSession st = stage(s);
  const Image same = draw(s, st.drawLists());
  State moved = st.panel(0).state();
  const int top = st.scene().model.bodyIndex("stack_4");
  ASSERT_GE(top, 0);
  moved.bodies[static_cast<size_t>(top)].x.x() += 0.02;
  const Image shifted = draw(s, {st.drawList(0, &moved)});
  const CompareResult r = compareImages(same, shifted, kTolerance);
  writePng((failureDir() / "tolerance_shifted_2cm.diff.png").string(), r.diff);
  std::cout << "a 2 cm move of the top box: " << r.summary() << "\n";
  EXPECT_FALSE(r.match) << "a 2 cm move passed as " << r.summary();
  EXPECT_GT(r.differing, 2 * kTolerance.maxShare * s.width * s.height) << r.summary();  // not a near miss
  // And the same frame drawn again is identical: the tolerance is not hiding noise.
  const CompareResult again = compareImages(same, draw(s, st.drawLists()), kTolerance);
  EXPECT_EQ(again.differing, 0) << again.summary();
}

// The pyramid's pixels differ from the background: drawn without its boxes, the frame changes
// wherever a box was, and a good share of the frame is boxes.
TEST(SnapshotTolerance, PyramidIsNotEmpty) {
  const Golden s{"pyramid", "pyramid.json", 0.0, "", [](ViewOptions& v, CameraOptions&) { v.hud = false; }};
  const RenderSession st = stage(s);
  std::vector<DrawList> full = st.drawLists();
  std::vector<DrawList> empty = full;
  auto& solids = empty[0].solids;
  solids.erase(std::remove_if(solids.begin(), solids.end(),
                              [&](const Instance& in) { return !st.scene().model.bodies[static_cast<size_t>(in.body)].isStatic; }),
               solids.end());
  ASSERT_EQ(solids.size(), 1u);  // the ground
  const Image withBoxes = draw(s, full), background = draw(s, empty);
  const CompareResult r = compareImages(background, withBoxes, CompareOptions{24, 1.0});
  EXPECT_GT(r.share, 0.08) << r.summary();
  // Every box centre projects onto a pixel that changed.
  const Camera& cam = full[0].camera;
  const float aspect = static_cast<float>(s.width) / s.height;
  int checked = 0;
  for (const Instance& in : full[0].solids) {
    if (st.scene().model.bodies[static_cast<size_t>(in.body)].isStatic) continue;
    const Eigen::Vector4f h = cam.projection(aspect) * cam.view() * Eigen::Vector4f(in.position.x(), in.position.y(), in.position.z(), 1);
    const int x = static_cast<int>((h.x() / h.w() * 0.5f + 0.5f) * s.width);
    const int y = static_cast<int>((0.5f - h.y() / h.w() * 0.5f) * s.height);
    if (x < 0 || y < 0 || x >= s.width || y >= s.height) continue;
    const uint8_t* a = withBoxes.pixel(x, y);
    const uint8_t* b = background.pixel(x, y);
    int d = 0;
    for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(a[c] - b[c]));
    EXPECT_GT(d, 24) << in.body << " at pixel " << x << "," << y;
    ++checked;
  }
  EXPECT_EQ(checked, 210);
}

TEST(SnapshotTolerance, MissingFontIsARenderErrorNamingIt) {
  RendererOptions o;
  o.fontPath = "/no/such/font.ttf";
  try {
    GlRenderer r(64, 64, o);
    FAIL() << "a missing font must be refused";
  } catch (const RenderError& e) {
    EXPECT_NE(std::string(e.what()).find("/no/such/font.ttf"), std::string::npos) << e.what();
  }
}

// Anti-aliasing: the default is FXAA on the CPU after the read-back; it changes a small share of
// the pixels, all of them on an edge of the frame drawn without anti-aliasing, and leaves every
// pixel opaque. 4x multisampling stays available.
TEST(AntiAliasing, FxaaBlendsEdgesOnlyAndMultisamplingStaysAvailable) {
  const Golden& s = kSnapshots[0];
  ASSERT_EQ(s.name, "stack");
  const std::vector<DrawList> lists = stage(s).drawLists();
  auto frame = [&](int samples, AntiAliasing aa, const std::string& info) {
    RendererOptions o;
    o.samples = samples;
    o.antiAliasing = aa;
    GlRenderer r(s.width, s.height, o);
    EXPECT_NE(r.glInfo().find(info), std::string::npos) << r.glInfo();
    return r.render(lists[0]);
  };
  EXPECT_EQ(RendererOptions{}.antiAliasing, AntiAliasing::Fxaa);
  EXPECT_EQ(RendererOptions{}.samples, 1);
  const Image none = frame(1, AntiAliasing::None, "no anti-aliasing"), fx = frame(1, AntiAliasing::Fxaa, "FXAA"),
              ms = frame(4, AntiAliasing::None, "4x MSAA");
  writePng((failureDir() / "aa_none.png").string(), none);
  writePng((failureDir() / "aa_fxaa.png").string(), fx);
  writePng((failureDir() / "aa_msaa4.png").string(), ms);
  for (const Image* img : {&none, &fx, &ms})
    for (size_t i = 3; i < img->rgba.size(); i += 4) ASSERT_EQ(img->rgba[i], 255);  // the luma in the alpha is gone

  const CompareResult c = compareImages(none, fx, CompareOptions{2, 1.0});
  std::cout << "FXAA against none: " << c.summary() << "\n";
  EXPECT_GT(c.share, 0.002);
  EXPECT_LT(c.share, 0.05);
  // Every changed pixel has a neighbour (or is one) across which the unfiltered frame jumps.
  auto luma = [](const Image& img, int x, int y) {
    const uint8_t* p = img.pixel(std::clamp(x, 0, img.width - 1), std::clamp(y, 0, img.height - 1));
    return 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
  };
  int offEdge = 0;
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x) {
      const uint8_t *a = none.pixel(x, y), *b = fx.pixel(x, y);
      if (std::max({std::abs(a[0] - b[0]), std::abs(a[1] - b[1]), std::abs(a[2] - b[2])}) <= 2) continue;
      double jump = 0;
      for (auto [dx, dy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}})
        jump = std::max(jump, std::abs(luma(none, x + dx, y + dy) - luma(none, x, y)));
      offEdge += jump < 8;
    }
  EXPECT_EQ(offEdge, 0);
  EXPECT_GT(compareImages(none, ms, CompareOptions{2, 1.0}).differing, 0);  // multisampling did something
}
