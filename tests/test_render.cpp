// The render library without a GL context: meshes, the scene builder's draw list, cameras,
// colours, text layout, comparison specs, images and their tolerant comparison, the video pipe,
// the frame sinks.
// (Pixels drawn by OSMesa are checked in test_snapshots.)
#include "physics/scene_file.h"
#include "physics/world.h"
#include "render/compare.h"
#include "render/frame_sink.h"
#include "render/fxaa.h"
#include "render/gl_renderer.h"
#include "render/image.h"
#include "render/meshes.h"
#include "render/scene_builder.h"
#include "render/text.h"
#include "render/video.h"
#include "run_substep.h"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <functional>
#include <limits>
#include <set>
#include <thread>

namespace fs = std::filesystem;
using namespace substep;
using namespace substep::render;

namespace {

Scene scene(const std::string& name) { return loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/" + name); }

fs::path scratch(const std::string& name) {
  fs::path d = fs::path(SUBSTEP_BINARY_DIR) / "test_render_out" /
               ::testing::UnitTest::GetInstance()->current_test_info()->name();
  fs::create_directories(d);
  return d / name;
}

Camera defaultCamera(const Scene& s) { return placeCamera(chooseCamera(s, {}), s.model, s.initial); }

// Where a world point lands in normalised device coordinates.
Eigen::Vector3f project(const Camera& c, float aspect, const Vec3f& p) {
  const Eigen::Vector4f h = c.projection(aspect) * c.view() * Eigen::Vector4f(p.x(), p.y(), p.z(), 1);
  return h.head<3>() / h.w();
}

}  // namespace

// ---- meshes ----

// Every triangle of every primitive is wound counter-clockwise seen from outside: its geometric
// normal agrees with its vertex normals. (Back faces are culled, so a wrong winding would hide faces.)
TEST(Meshes, PrimitivesAreClosedOutwardWoundAndUnitSized) {
  for (int id = 0; id < kFirstCustomMesh; ++id) {
    for (int level = 0; level < (isRound(id) ? kRoundLevels : 1); ++level) {
      SCOPED_TRACE("level " + std::to_string(level));
      const MeshData m = primitiveMesh(id, level);
      ASSERT_EQ(m.indices.size() % 3, 0u) << id;
      ASSERT_FALSE(m.indices.empty()) << id;
      for (size_t t = 0; t < m.indices.size(); t += 3) {
        const MeshVertex& a = m.vertices[m.indices[t]];
        const MeshVertex& b = m.vertices[m.indices[t + 1]];
        const MeshVertex& c = m.vertices[m.indices[t + 2]];
        // Positions as the capsule's stretch would place them, so its side quads are not degenerate.
        auto pos = [](const MeshVertex& v) { return Vec3f(v.position[0], v.position[1] + v.capSign, v.position[2]); };
        const Vec3f g = (pos(b) - pos(a)).cross(pos(c) - pos(a));
        if (g.norm() < 1e-7f) continue;  // the poles of a UV sphere
        const Vec3f n = Vec3f(a.normal[0], a.normal[1], a.normal[2]) + Vec3f(b.normal[0], b.normal[1], b.normal[2]) +
                        Vec3f(c.normal[0], c.normal[1], c.normal[2]);
        EXPECT_GT(g.dot(n), 0) << "mesh " << id << " triangle " << t / 3;
      }
      for (const MeshVertex& v : m.vertices) {
        const Vec3f p(v.position[0], v.position[1], v.position[2]);
        EXPECT_LE(p.cwiseAbs().maxCoeff(), 1.0f + 1e-5f) << id;
        EXPECT_NEAR(Vec3f(v.normal[0], v.normal[1], v.normal[2]).norm(), 1.0f, 1e-5f) << id;
      }
    }
  }
  const MeshData box = boxMesh();
  EXPECT_EQ(box.vertices.size(), 24u);
  EXPECT_EQ(box.indices.size(), 36u);
  for (const MeshVertex& v : sphereMesh().vertices)
    EXPECT_NEAR(Vec3f(v.position[0], v.position[1], v.position[2]).norm(), 1.0f, 1e-5f);
  // Capsule: the upper hemisphere moves up with the stretch, the lower down.
  for (const MeshVertex& v : capsuleMesh().vertices) {
    if (v.position[1] > 1e-4f) {
      EXPECT_EQ(v.capSign, 1.0f);
    }
    if (v.position[1] < -1e-4f) {
      EXPECT_EQ(v.capSign, -1.0f);
    }
  }
}

// A round primitive's level is the coarsest whose silhouette misses the circle by at most the
// allowed error; large ones keep the finest level (the only one before levels existed).
TEST(Meshes, RoundLevelsAreTheCoarsestWithinTheError) {
  auto error = [](float radius, int level) {
    return radius * (1 - std::cos(3.14159265f / static_cast<float>(kRoundSlices[level])));
  };
  int previous = 0;
  for (float r = 0.1f; r < 200; r *= 1.05f) {
    const int level = roundLevel(r);
    EXPECT_GE(level, previous) << r;  // never coarser for a larger radius
    previous = level;
    if (level < kFinestLevel) {
      EXPECT_LE(error(r, level), kMaxSilhouetteError) << r;
    }
    if (level > 0) {
      EXPECT_GT(error(r, level - 1), kMaxSilhouetteError) << r;
    }
  }
  EXPECT_EQ(roundLevel(0.5f), 0);
  EXPECT_EQ(roundLevel(1000.0f), kFinestLevel);
  EXPECT_EQ(roundLevel(std::numeric_limits<float>::infinity()), kFinestLevel);
  // Slices, stacks and capsule rings follow the level: the finest is the mesh used before.
  EXPECT_EQ(primitiveMesh(kSphereMesh).indices.size(), sphereMesh(32, 16).indices.size());
  EXPECT_EQ(primitiveMesh(kCapsuleMesh).indices.size(), capsuleMesh(32, 8).indices.size());
  EXPECT_LT(primitiveMesh(kCapsuleMesh, 1).indices.size(), primitiveMesh(kCapsuleMesh, 2).indices.size());
  EXPECT_THROW(primitiveMesh(kBoxMesh, kRoundLevels), std::invalid_argument);
}

TEST(Meshes, ModelMeshesKeepCreasesAndSmoothCurves) {
  // A cube: 90 degree edges stay sharp, so every corner has its face's normal.
  Mesh cube;
  for (int i = 0; i < 8; ++i) cube.vertices.emplace_back(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1);
  cube.triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                    {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  const MeshData m = modelMesh(cube);
  ASSERT_EQ(m.vertices.size(), 36u);
  std::set<std::tuple<int, int, int>> normals;
  for (const MeshVertex& v : m.vertices)
    normals.insert({static_cast<int>(std::lround(v.normal[0])), static_cast<int>(std::lround(v.normal[1])),
                    static_cast<int>(std::lround(v.normal[2]))});
  EXPECT_EQ(normals.size(), 6u);
  // The bowl: a curved surface gets normals between its faces' normals.
  const Scene shapes = scene("shapes.json");
  const Mesh& bowl = *shapes.model.bodies[static_cast<size_t>(shapes.model.bodyIndex("bowl"))].shape.mesh;
  const MeshData b = modelMesh(bowl);
  EXPECT_EQ(b.vertices.size(), 3 * bowl.triangles.size());
  int smoothed = 0;
  for (size_t t = 0; t < b.vertices.size(); t += 3) {
    const Vec3f n0(b.vertices[t].normal[0], b.vertices[t].normal[1], b.vertices[t].normal[2]);
    const Vec3f n1(b.vertices[t + 1].normal[0], b.vertices[t + 1].normal[1], b.vertices[t + 1].normal[2]);
    smoothed += (n0 - n1).norm() > 1e-3f;
  }
  EXPECT_GT(smoothed, static_cast<int>(bowl.triangles.size() / 2));
}

// ---- the scene builder ----

TEST(SceneBuilder, OneInstancePerBodyWithItsShapeAndPose) {
  const Scene s = scene("shapes.json");
  const DrawList dl = buildDrawList(s.model, takeSnapshot(s.model, s.initial), defaultCamera(s), {}, {});
  ASSERT_EQ(dl.solids.size(), s.model.bodies.size());
  for (const Instance& in : dl.solids) {
    const Body& b = s.model.bodies[static_cast<size_t>(in.body)];
    const BodyState& st = s.initial.bodies[static_cast<size_t>(in.body)];
    EXPECT_TRUE(in.position.isApprox(st.x.cast<float>())) << b.name;
    EXPECT_TRUE(in.rotation.isApprox(st.q.cast<float>().normalized(), 1e-5f)) << b.name;
    switch (b.shape.type) {
      case ShapeType::Box:
        EXPECT_EQ(in.mesh, kBoxMesh);
        EXPECT_TRUE(in.scale.isApprox(b.shape.halfExtents.cast<float>()));
        break;
      case ShapeType::Sphere: EXPECT_EQ(in.mesh, kSphereMesh); break;
      case ShapeType::Capsule:
        EXPECT_EQ(in.mesh, kCapsuleMesh);
        EXPECT_FLOAT_EQ(in.scale.x(), static_cast<float>(b.shape.radius));
        EXPECT_FLOAT_EQ(in.stretch, static_cast<float>(b.shape.halfHeight));
        break;
      case ShapeType::Cylinder:
        EXPECT_EQ(in.mesh, kCylinderMesh);
        EXPECT_FLOAT_EQ(in.scale.y(), static_cast<float>(b.shape.halfHeight));
        break;
      case ShapeType::ConvexMesh:
      case ShapeType::TriangleMesh:
        ASSERT_GE(in.mesh, kFirstCustomMesh);
        EXPECT_EQ(dl.meshes.at(static_cast<size_t>(in.mesh - kFirstCustomMesh)), b.shape.mesh);
        break;
      default: ADD_FAILURE() << "unexpected shape";
    }
    // Static bodies are grounds: grey, with a grid.
    EXPECT_EQ((in.flags & kGrid) != 0, b.isStatic) << b.name;
  }
  EXPECT_EQ(dl.meshes.size(), 2u);  // the bowl and the gem
  EXPECT_TRUE(dl.overlays.empty());
}

// A ground that every other body lies on or above casts no shadow (it could shade nothing but
// itself); the steps on it, and a ground with a body hanging below its top beside it, still do.
TEST(SceneBuilder, GroundsBelowEverythingCastNoShadow) {
  const Scene pile = scene("ragdoll_pile.json");
  State settled = pile.initial;
  auto flagsOf = [](const DrawList& dl, const Model& m, const std::string& name) {
    for (const Instance& in : dl.solids)
      if (in.body == m.bodyIndex(name)) return in.flags;
    ADD_FAILURE() << name;
    return 0u;
  };
  const DrawList dl = buildDrawList(pile.model, takeSnapshot(pile.model, settled), defaultCamera(pile), {}, {});
  EXPECT_TRUE(flagsOf(dl, pile.model, "ground") & kNoShadow);
  EXPECT_FALSE(flagsOf(dl, pile.model, "step_0") & kNoShadow);
  for (const Instance& in : dl.solids) {
    if (!pile.model.bodies[static_cast<size_t>(in.body)].isStatic) {
      EXPECT_FALSE(in.flags & kNoShadow);
    }
  }
  // A body sunk 10 cm into the ground's top (beyond a resting contact): the ground casts again.
  const int b = pile.model.bodyIndex("ragdoll_0_pelvis");
  ASSERT_GE(b, 0);
  settled.bodies[static_cast<size_t>(b)].x.y() = 0.0;
  EXPECT_FALSE(flagsOf(buildDrawList(pile.model, takeSnapshot(pile.model, settled), defaultCamera(pile), {}, {}),
                       pile.model, "ground") &
               kNoShadow);
}

TEST(SceneBuilder, PlanesBecomeLargeQuadsFacingTheirNormal) {
  Scene s = parseScene(R"({"bodies": [
      {"name": "floor", "static": true, "shape": {"type": "plane", "normal": [0, 0, 1], "offset": 2}},
      {"name": "ball", "shape": {"type": "sphere", "radius": 0.5}, "position": [0, 0, 5]}]})",
                       "plane.json", ".");
  const DrawList dl = buildDrawList(s.model, takeSnapshot(s.model, s.initial), defaultCamera(s), {}, {});
  const Instance& q = dl.solids[0];
  EXPECT_EQ(q.mesh, kQuadMesh);
  EXPECT_TRUE((q.rotation * Vec3f::UnitY()).isApprox(Vec3f::UnitZ(), 1e-5f));
  EXPECT_NEAR(q.position.z(), 2.0f, 1e-4f);  // on the plane
  EXPECT_GE(q.scale.x(), 100.0f);
  EXPECT_TRUE(q.flags & kNoShadow);
}

TEST(SceneBuilder, ColoursTellBodiesApartAndShowQuantities) {
  Scene s = scene("stack.json");
  // One group (a single stack): auto colours by body, five distinct colours.
  const DrawList byBody = buildDrawList(s.model, takeSnapshot(s.model, s.initial), defaultCamera(s), {}, {});
  std::set<std::vector<int>> colours;
  for (const Instance& in : byBody.solids)
    if (!s.model.bodies[static_cast<size_t>(in.body)].isStatic)
      colours.insert({int(in.colour.x() * 255), int(in.colour.y() * 255), int(in.colour.z() * 255)});
  EXPECT_EQ(colours.size(), 5u);

  // Speed and activity: one box moving fast, the others at rest.
  State moving = s.initial;
  const int top = s.model.bodyIndex("stack_4");
  ASSERT_GE(top, 0);
  moving.bodies[static_cast<size_t>(top)].v = Vec3(10, 0, 0);
  ViewOptions v;
  v.colour = ColourMode::Speed;
  const DrawList speed = buildDrawList(s.model, takeSnapshot(s.model, moving), defaultCamera(s), v, {});
  EXPECT_TRUE(speed.solids[static_cast<size_t>(top)].colour.head<3>().isApprox(rampColour(1.0)));
  EXPECT_TRUE(speed.solids[static_cast<size_t>(top) - 1].colour.head<3>().isApprox(rampColour(0.0)));
  EXPECT_FALSE(rampColour(0.0).isApprox(rampColour(1.0)));
  v.colour = ColourMode::Activity;
  const DrawList act = buildDrawList(s.model, takeSnapshot(s.model, moving), defaultCamera(s), v, {});
  EXPECT_FALSE(act.solids[static_cast<size_t>(top)].colour.isApprox(act.solids[static_cast<size_t>(top) - 1].colour));
  EXPECT_TRUE(act.solids[1].colour.isApprox(act.solids[2].colour));  // both at rest
  // Asleep (the snapshot's list): a third colour, named in the legend.
  Snapshot sleeping = takeSnapshot(s.model, moving);
  sleeping.asleep = {2};
  const DrawList asleep = buildDrawList(s.model, sleeping, defaultCamera(s), v, {});
  EXPECT_FALSE(asleep.solids[2].colour.isApprox(asleep.solids[1].colour));
  EXPECT_FALSE(asleep.solids[2].colour.isApprox(asleep.solids[static_cast<size_t>(top)].colour));
  bool named = false;
  for (const auto& line : asleep.footer) named = named || line.text.find("asleep") != std::string::npos;
  EXPECT_TRUE(named);

  // Error: sink the top box 5 cm into the one below; a step finds the contact, and its snapshot
  // measures what is left of the overlap at the step's end.
  State sunk = s.initial;
  sunk.bodies[static_cast<size_t>(top)].x.y() -= 0.05;
  SolverSettings settings = resolve(s.solver);
  World world(s.model, settings, sunk);
  world.step();
  Snapshot snap = takeSnapshot(world);
  std::vector<double> err = bodyErrors(s.model, snap);
  EXPECT_GT(err[static_cast<size_t>(top)], 0.001);  // pushed out by most of the 5 cm in one step
  EXPECT_GE(err[static_cast<size_t>(top) - 1], err[static_cast<size_t>(top)]);  // both sides of the contact
  EXPECT_LT(err[1], 0.005);  // the bottom box sits on the ground
  // The depths are the snapshot's (a recording's), not measured again from the state.
  for (const ManifoldSnap& m : snap.manifolds)
    if (m.a == top || m.b == top) snap.contacts[static_cast<size_t>(m.first)].depth = 0.07f;
  err = bodyErrors(s.model, snap);
  EXPECT_NEAR(err[static_cast<size_t>(top)], 0.07, 1e-7);
  v.colour = ColourMode::Error;
  const DrawList e = buildDrawList(s.model, snap, defaultCamera(s), v, {});
  EXPECT_TRUE(e.solids[static_cast<size_t>(top)].colour.head<3>().isApprox(rampColour(1.0)));
  EXPECT_FALSE(e.footer.empty());  // the legend says what the colours mean

  // Highlight: only the named body glows.
  v = ViewOptions{};
  v.highlight = {"stack_2"};
  const DrawList h = buildDrawList(s.model, takeSnapshot(s.model, s.initial), defaultCamera(s), v, {});
  for (const Instance& in : h.solids) EXPECT_EQ(in.highlight, in.body == s.model.bodyIndex("stack_2") ? 1.0f : 0.0f);
}

TEST(SceneBuilder, GroupsGetOneHueWithDistinctShades) {
  const Scene s = scene("pile.json");  // columns in ten groups
  ViewOptions v;
  const DrawList dl = buildDrawList(s.model, takeSnapshot(s.model, s.initial), defaultCamera(s), v, {});
  std::map<int, std::set<std::vector<int>>> perGroup;
  for (const Instance& in : dl.solids) {
    const Body& b = s.model.bodies[static_cast<size_t>(in.body)];
    if (!b.isStatic) perGroup[b.group].insert({int(in.colour.x() * 255), int(in.colour.y() * 255), int(in.colour.z() * 255)});
  }
  ASSERT_EQ(perGroup.size(), 10u);
  for (const auto& [g, cs] : perGroup) EXPECT_GT(cs.size(), 5u) << "group " << g;
  EXPECT_FALSE(groupColour(0, 0).isApprox(groupColour(1, 0)));
}

TEST(SceneBuilder, ContactOverlaysShowPointsAndNormals) {
  const Scene s = scene("box_on_ground.json");
  World world(s.model, resolve(s.solver), s.initial);
  world.step();
  ASSERT_FALSE(world.manifolds().empty());
  int points = 0;
  for (const Manifold& m : world.manifolds()) points += m.count;
  ASSERT_EQ(points, 4);
  ViewOptions v;
  v.contacts = true;
  const DrawList dl = buildDrawList(s.model, takeSnapshot(world), defaultCamera(s), v, {});
  ASSERT_EQ(dl.overlays.size(), 2u * points);
  const Manifold& m = world.manifolds()[0];
  const Vec3f intoA = (world.state().bodies[static_cast<size_t>(m.a)].x - world.state().bodies[static_cast<size_t>(m.b)].x)
                          .cast<float>()
                          .normalized();
  for (const Instance& in : dl.overlays) {
    EXPECT_TRUE(in.flags & kNoShadow);
    if (in.mesh == kSphereMesh) {
      EXPECT_NEAR(in.position.y(), 0.0f, 0.01f);  // on the ground's surface
    } else {
      EXPECT_EQ(in.mesh, kCylinderMesh);
      EXPECT_GT((in.rotation * Vec3f::UnitY()).dot(intoA), 0.99f);  // the normal, from B into A
    }
  }
  // Off by default.
  EXPECT_TRUE(buildDrawList(s.model, takeSnapshot(world), defaultCamera(s), {}, {}).overlays.empty());
}

TEST(SceneBuilder, JointOverlaysMarkAnchorsAndArms) {
  const Scene s = scene("pendulum_chain.json");
  ViewOptions v;
  v.joints = true;
  const DrawList dl = buildDrawList(s.model, takeSnapshot(s.model, s.initial), defaultCamera(s), v, {});
  // Two arms and an anchor per ball joint (the two anchors coincide at the start).
  EXPECT_EQ(dl.overlays.size(), 3 * s.model.joints.size());
  const Joint& j = s.model.joints[0];
  const Vec3f anchor = s.initial.bodies[static_cast<size_t>(j.bodyA)].pose().apply(j.localAnchorA).cast<float>();
  bool found = false;
  for (const Instance& in : dl.overlays) found |= in.mesh == kSphereMesh && in.position.isApprox(anchor, 1e-4f);
  EXPECT_TRUE(found);
}

TEST(SceneBuilder, HudSaysSceneSettingsTimeAndCost) {
  const Scene s = scene("stack.json");
  SolverOverrides o;
  o.set(&SolverSettings::algorithm, Algorithm::A5);
  SolverSettings a5 = resolve(o);  // a5's own defaults (blocks on)
  a5.substeps = 4;
  a5.iterations = 2;
  a5.kappa = 1.1;
  a5.tau = 0.9;
  const std::string line = settingsLine(a5);
  for (const char* part : {"a5", "n=4", "m=2", "κ=1.1", "τ=0.9", "h=1/60"})
    EXPECT_NE(line.find(part), std::string::npos) << line << " lacks " << part;
  EXPECT_EQ(settingsLine(a5, LineDetail::Brief), "a5 n=4 m=2 κ=1.1 τ=0.9");
  SolverSettings a2;
  a2.iterations = 4;
  EXPECT_EQ(settingsLine(a2, LineDetail::Brief), "a2 m=4");
  a2.warmStart = a2.splitImpulse = true;
  EXPECT_EQ(settingsLine(a2, LineDetail::Brief), "a2 m=4 warm split");
  EXPECT_NE(settingsLine(a2, LineDetail::Hud).find("  warm  split"), std::string::npos) << settingsLine(a2, LineDetail::Hud);
  a2.warmStart = a2.splitImpulse = false;
  HudInfo hud;
  hud.scene = sceneLine(s);
  hud.settings = line;
  hud.time = 1.25;
  hud.stepMs = 0.5;
  const DrawList dl = buildDrawList(s.model, takeSnapshot(s.model, s.initial), defaultCamera(s), {}, hud);
  ASSERT_EQ(dl.hud.size(), 3u);
  EXPECT_EQ(dl.hud[0].text, "stack: 5 bodies, 0 joints");
  EXPECT_EQ(dl.hud[2].text, "t = 1.250 s    step 0.50 ms");
  hud.stepMs = std::numeric_limits<double>::quiet_NaN();
  hud.status = "diverged";
  const DrawList noCost = buildDrawList(s.model, takeSnapshot(s.model, s.initial), defaultCamera(s), {}, hud);
  EXPECT_EQ(noCost.hud[2].text, "t = 1.250 s");
  EXPECT_EQ(noCost.hud[3].text, "diverged");
  ViewOptions off;
  off.hud = false;
  EXPECT_TRUE(buildDrawList(s.model, takeSnapshot(s.model, s.initial), defaultCamera(s), off, hud).hud.empty());
}

// ---- cameras ----

TEST(Camera, YawPitchAndDistancePlaceTheEye) {
  const Scene s = scene("stack.json");
  CameraPreset p;
  p.target = Vec3(1, 2, 3);
  p.distance = 10;
  p.yaw = 0;
  p.pitch = 0;
  Camera c = placeCamera(p, s.model, s.initial);
  EXPECT_TRUE(c.eye.isApprox(Vec3f(1, 2, 13)));  // yaw 0 looks along -Z
  p.yaw = 90;
  c = placeCamera(p, s.model, s.initial);
  EXPECT_TRUE(c.eye.isApprox(Vec3f(11, 2, 3), 1e-5f));
  p.pitch = 30;
  c = placeCamera(p, s.model, s.initial);
  EXPECT_NEAR(c.eye.y(), 2 + 10 * std::sin(30 * M_PI / 180), 1e-4);
  // The view matrix puts the target straight ahead at the distance.
  const Eigen::Vector4f t = c.view() * Eigen::Vector4f(1, 2, 3, 1);
  EXPECT_TRUE(t.head<3>().isApprox(Vec3f(0, 0, -10), 1e-4f));
  // A point on the edge of the vertical field of view projects to the top of the frame.
  p = CameraPreset{};
  p.yaw = p.pitch = 0;
  c = placeCamera(p, s.model, s.initial);
  const float half = static_cast<float>(std::tan(22.5 * M_PI / 180));
  EXPECT_NEAR(project(c, 16.0f / 9, Vec3f(0, half * 10, 0)).y(), 1.0f, 1e-4f);
  // A narrow panel keeps the preset's horizontal extent.
  const float x169 = project(c, 16.0f / 9, Vec3f(3, 0, 0)).x();
  EXPECT_NEAR(project(c, 0.9f, Vec3f(3, 0, 0)).x(), x169, 1e-4f);
}

TEST(Camera, FollowOrbitPresetsAndFit) {
  Scene s = scene("stack.json");
  CameraOptions o;
  o.preset = "side";
  EXPECT_EQ(chooseCamera(s, o).name, "side");
  o.preset = "nope";
  try {
    chooseCamera(s, o);
    FAIL() << "an unknown camera must be refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("default, side"), std::string::npos) << e.what();
  }
  o = CameraOptions{};
  o.follow = "stack_4";
  o.distance = 5;
  const CameraPreset f = chooseCamera(s, o);
  State st = s.initial;
  st.bodies[static_cast<size_t>(s.model.bodyIndex("stack_4"))].x = Vec3(7, 8, 9);
  EXPECT_TRUE(placeCamera(f, s.model, st).target.isApprox(Vec3f(7, 8, 9)));
  o.follow = "ghost";
  EXPECT_THROW(chooseCamera(s, o), std::invalid_argument);
  // Orbit: a quarter turn after 1 s at 90 degrees per second.
  CameraPreset p;
  p.yaw = 0;
  p.pitch = 0;
  st.time = 1.0;
  const Camera c = placeCamera(p, s.model, st, 90);
  EXPECT_TRUE((c.eye - c.target).normalized().isApprox(Vec3f::UnitX(), 1e-5f));
  // No presets: a fitted camera sees every dynamic body.
  s.cameras.clear();
  const Scene pile = [] {
    Scene p = scene("pile.json");
    p.cameras.clear();
    return p;
  }();
  const Camera fit = placeCamera(chooseCamera(pile, {}), pile.model, pile.initial);
  for (size_t i = 0; i < pile.model.bodies.size(); ++i) {
    if (pile.model.bodies[i].isStatic) continue;
    const Eigen::Vector3f ndc = project(fit, 16.0f / 9, pile.initial.bodies[i].x.cast<float>());
    EXPECT_LT(std::abs(ndc.x()), 1.0f);
    EXPECT_LT(std::abs(ndc.y()), 1.0f);
  }
}

TEST(Camera, GridLayoutTilesTheFrame) {
  for (int panels = 1; panels <= 4; ++panels) {
    const auto vps = gridLayout(1280, 720, panels);
    ASSERT_EQ(static_cast<int>(vps.size()), panels);
    long long area = 0;
    for (const Viewport& v : vps) {
      area += static_cast<long long>(v.width) * v.height;
      EXPECT_GE(v.x, 0);
      EXPECT_LE(v.x + v.width, 1280);
      EXPECT_LE(v.y + v.height, 720);
    }
    // Up to two panels fill the frame; three leave the fourth cell empty.
    EXPECT_EQ(area, panels == 3 ? 1280LL * 720 * 3 / 4 : 1280LL * 720);
  }
}

// ---- comparison specs ----

TEST(CompareSpecs, TheIssueExampleAndEveryKey) {
  auto specs = parseCompareSpecs("a2:m=4,a5:n=4");
  ASSERT_EQ(specs.size(), 2u);
  EXPECT_EQ(specs[0].text, "a2:m=4");
  EXPECT_EQ(*specs[0].overrides.algorithm(), Algorithm::A2);
  EXPECT_EQ(*specs[0].overrides.get(&SolverSettings::iterations), 4);
  EXPECT_EQ(*specs[1].overrides.algorithm(), Algorithm::A5);
  EXPECT_EQ(*specs[1].overrides.get(&SolverSettings::substeps), 4);
  EXPECT_FALSE(specs[1].overrides.get(&SolverSettings::iterations));

  specs = parseCompareSpecs("a1, a5:n=8:m=2:kappa=1.1:tau=0.9:warm=on:split=on ,a2:omega=1.3;tol=1e-4;dt=0.01,a3:preset=4-hard");
  ASSERT_EQ(specs.size(), 4u);
  EXPECT_EQ(*specs[0].overrides.algorithm(), Algorithm::A1);
  const SolverOverrides& a5 = specs[1].overrides;
  EXPECT_EQ(*a5.get(&SolverSettings::substeps), 8);
  EXPECT_EQ(*a5.get(&SolverSettings::iterations), 2);
  EXPECT_DOUBLE_EQ(*a5.get(&SolverSettings::kappa), 1.1);
  EXPECT_DOUBLE_EQ(*a5.get(&SolverSettings::tau), 0.9);
  EXPECT_TRUE(*a5.get(&SolverSettings::warmStart));
  EXPECT_TRUE(*a5.get(&SolverSettings::splitImpulse));
  EXPECT_DOUBLE_EQ(*specs[2].overrides.get(&SolverSettings::omega), 1.3);
  EXPECT_DOUBLE_EQ(*specs[2].overrides.get(&SolverSettings::tolerance), 1e-4);
  EXPECT_DOUBLE_EQ(*specs[2].overrides.get(&SolverSettings::dt), 0.01);
  EXPECT_EQ(*specs[3].overrides.preset(), "4-hard");
}

TEST(CompareSpecs, BadSpecsSayWhatIsWrong) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"a2", "2 to 4 panels"},
      {"a1,a2,a2:m=3,a2:m=4,a2:m=5", "2 to 4 panels"},
      {"a9,a2", "unknown algorithm \"a9\""},
      {"a2:m=0,a1", "m: expected an integer in [1, 100000], got \"0\""},
      {"a2:m=four,a1", "m: expected an integer"},
      {"a2:m=4x,a1", "m: expected an integer"},
      {"a2:omega=2,a1", "omega: expected a number in (0, 2)"},
      {"a2:frob=1,a1", "unknown key \"frob\""},
      {"a2:m,a1", "expected key=value"},
      {"a2,,a1", "an empty method"},
      {"a2:m=nan,a1", "m: expected an integer"},
      {"a5:kappa=inf,a1", "kappa: expected a number in (0, 10]"},
      {"a5:n=4:n=2,a1", "n is given twice"},
      {"a5:warm=maybe,a1", "warm: expected on or off"},
  };
  for (const auto& [spec, fragment] : cases) {
    try {
      parseCompareSpecs(spec);
      ADD_FAILURE() << spec << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << spec << ": " << e.what();
    }
  }
}

// ---- images ----

TEST(Images, PngRoundTripAndAtomicWrite) {
  Image img(7, 5, 0x102030ff);
  img.pixel(3, 2)[0] = 200;
  img.pixel(6, 4)[3] = 128;
  const Image back = decodePng(encodePng(img));
  EXPECT_EQ(back.width, 7);
  EXPECT_EQ(back.height, 5);
  EXPECT_EQ(back.rgba, img.rgba);
  const fs::path f = scratch("round.png");
  writePng(f.string(), img);
  EXPECT_EQ(readPng(f.string()).rgba, img.rgba);
  for (const auto& e : fs::directory_iterator(f.parent_path()))
    EXPECT_EQ(e.path().string().find(".part"), std::string::npos) << e.path();
  EXPECT_THROW(writePng("/proc/no/such/dir/x.png", img), std::runtime_error);
  EXPECT_THROW(readPng(scratch("missing.png").string()), std::runtime_error);
  EXPECT_THROW(decodePng({1, 2, 3}), std::runtime_error);
}

// The stream's JPEG (libjpeg-turbo): decodes to the frame within its quality, more quality costs
// more bytes, threads encoding at once get the same bytes, and an empty frame is an error.
TEST(Images, JpegKeepsTheFrameAndIsThreadSafe) {
  Image img(320, 180);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      uint8_t* p = img.pixel(x, y);
      p[0] = static_cast<uint8_t>(x * 255 / img.width);
      p[1] = static_cast<uint8_t>(y * 255 / img.height);
      p[2] = (x / 40 + y / 30) % 2 ? 220 : 40;  // hard edges, as a frame's bodies have
      p[3] = 255;
    }
  auto psnr = [&](const std::string& jpeg) {
    const Image d = decodeImage(jpeg.data(), jpeg.size());
    EXPECT_EQ(d.width, img.width);
    EXPECT_EQ(d.height, img.height);
    double se = 0;
    for (size_t i = 0; i < img.rgba.size(); i += 4)
      for (int c = 0; c < 3; ++c) se += std::pow(double(img.rgba[i + c]) - d.rgba[i + c], 2);
    return 10 * std::log10(255.0 * 255 / (se / (3.0 * img.width * img.height)));
  };
  const std::string q80 = encodeJpeg(img, 80), q30 = encodeJpeg(img, 30), q95 = encodeJpeg(img, 95);
  EXPECT_GT(psnr(q80), 30);
  EXPECT_GT(psnr(q95), psnr(q80));
  EXPECT_GT(psnr(q80), psnr(q30));
  EXPECT_GT(q95.size(), q80.size());
  EXPECT_GT(q80.size(), q30.size());
  std::vector<std::string> out(4);
  std::vector<std::thread> threads;
  for (auto& o : out) threads.emplace_back([&o, &img] { for (int k = 0; k < 20; ++k) o = encodeJpeg(img, 80); });
  for (auto& t : threads) t.join();
  for (const auto& o : out) EXPECT_EQ(o, q80);
  EXPECT_THROW(encodeJpeg(Image(), 80), std::runtime_error);
}

TEST(Images, ComparisonToleratesRoundingButNotChange) {
  Image a(100, 100, 0x808080ff), b = a;
  CompareOptions o;
  o.threshold = 8;
  o.maxShare = 0.001;  // 10 pixels of 10000
  CompareResult r = compareImages(a, b, o);
  EXPECT_TRUE(r.match);
  EXPECT_EQ(r.differing, 0);
  // Rounding: every pixel off by a few levels.
  for (size_t i = 0; i < b.rgba.size(); i += 4) b.rgba[i] = static_cast<uint8_t>(b.rgba[i] + 3);
  r = compareImages(a, b, o);
  EXPECT_TRUE(r.match) << r.summary();
  EXPECT_EQ(r.maxDelta, 3);
  // A few changed pixels are tolerated, more are not.
  for (int k = 0; k < 10; ++k) b.pixel(k, 0)[1] = 0;
  r = compareImages(a, b, o);
  EXPECT_TRUE(r.match) << r.summary();
  EXPECT_EQ(r.differing, 10);
  b.pixel(50, 50)[2] = 255;
  r = compareImages(a, b, o);
  EXPECT_FALSE(r.match);
  EXPECT_EQ(r.differing, 11);
  EXPECT_NEAR(r.share, 0.0011, 1e-12);
  // The diff image marks the changed pixels red and keeps the rest dim.
  EXPECT_EQ(r.diff.pixel(50, 50)[0], 255);
  EXPECT_EQ(r.diff.pixel(50, 50)[1], 0);
  EXPECT_LT(r.diff.pixel(20, 20)[0], 100);
  EXPECT_FALSE(compareImages(a, Image(100, 99), o).match);
}

// A frame drawn smaller shown at a clip's size: flat stays flat, the same size is a copy, an
// edge stays where it was (as a share of the width), a gradient stays a gradient.
TEST(Images, ResizedKeepsColoursAndPlaces) {
  const Image flat(40, 30, 0x336699ffu);
  const Image big = resized(flat, 64, 48);
  ASSERT_EQ(big.width, 64);
  ASSERT_EQ(big.height, 48);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) ASSERT_EQ(std::vector<int>(big.pixel(x, y), big.pixel(x, y) + 4), (std::vector<int>{0x33, 0x66, 0x99, 0xff}));
  Image ramp(32, 8);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 32; ++x) {
      uint8_t* p = ramp.pixel(x, y);
      p[0] = static_cast<uint8_t>(x < 16 ? 0 : 255), p[1] = static_cast<uint8_t>(8 * x), p[2] = 0, p[3] = 255;
    }
  EXPECT_EQ(resized(ramp, 32, 8).rgba, ramp.rgba);
  const Image up = resized(ramp, 64, 16);
  for (int x = 0; x < 64; ++x) {
    if (x < 31) {
      EXPECT_EQ(up.pixel(x, 5)[0], 0) << x;
    }
    if (x > 32) {
      EXPECT_EQ(up.pixel(x, 5)[0], 255) << x;
    }
    if (x > 0) {
      EXPECT_GE(up.pixel(x, 5)[1], up.pixel(x - 1, 5)[1]) << x;
    }
  }
  EXPECT_NEAR(up.pixel(33, 5)[1], 8 * (33.5 / 2 - 0.5), 1);  // the source's value at that place
}

// ---- anti-aliasing (render/fxaa.h) ----

namespace {

constexpr uint8_t kDark[3] = {40, 40, 60}, kBright[3] = {230, 230, 230};

// A frame as the shaders leave it: RGBA with the luma (and the smooth flag) in the alpha.
Image lumaFrame(int w, int h, const std::function<bool(int, int)>& bright,
                const std::function<bool(int, int)>& smooth = nullptr) {
  Image img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      uint8_t* p = img.pixel(x, y);
      const uint8_t* c = bright(x, y) ? kBright : kDark;
      p[0] = c[0], p[1] = c[1], p[2] = c[2];
      p[3] = encodeLumaAlpha((0.299f * c[0] + 0.587f * c[1] + 0.114f * c[2]) / 255, smooth && smooth(x, y));
    }
  return img;
}

double brightness(const uint8_t* p) { return (p[0] - kDark[0]) / double(kBright[0] - kDark[0]); }

// Bright above the line y = 20 + x / 8 (pixel centres): a near-horizontal edge in 8-pixel steps.
bool aboveLine(int x, int y) { return y + 0.5 < 20 + (x + 0.5) / 8; }

}  // namespace

TEST(Fxaa, FlatFramesAreCopiedOpaque) {
  const Image in = lumaFrame(64, 48, [](int x, int) { return x < 32; });  // one vertical edge, straight
  Image out;
  fxaa(in.rgba.data(), 64 * 4, 64, 48, out);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      EXPECT_EQ(out.pixel(x, y)[3], 255);
      if (x < 30 || x > 33) {
        for (int c = 0; c < 3; ++c) ASSERT_EQ(out.pixel(x, y)[c], in.pixel(x, y)[c]) << x << "," << y;
      }
    }
  const Image flat = lumaFrame(16, 16, [](int, int) { return true; });
  EXPECT_EQ(fxaa(flat.rgba.data(), 16 * 4, 16, 16, out).edgePixels, 0);
}

// The aliased staircase becomes a ramp: along the edge, each column's share of bright comes
// close to the area above the line, where the aliased frame is off by up to half a pixel.
TEST(Fxaa, StairStepsBecomeARamp) {
  const int w = 96, h = 40;
  const Image in = lumaFrame(w, h, aboveLine);
  Image out;
  const FxaaStats st = fxaa(in.rgba.data(), w * 4, w, h, out);
  EXPECT_GT(st.edgePixels, w / 2);
  double errIn = 0, errOut = 0;
  int mixed = 0;
  for (int x = 16; x < w - 16; ++x) {
    const double exact = 20 + (x + 0.5) / 8;  // rows of bright in column x
    double sumIn = 0, sumOut = 0;
    for (int y = 0; y < h; ++y) {
      sumIn += brightness(in.pixel(x, y));
      sumOut += brightness(out.pixel(x, y));
      const double b = brightness(out.pixel(x, y));
      mixed += b > 0.05 && b < 0.95;
      if (std::abs(y - exact) > 3) {
        for (int c = 0; c < 3; ++c) ASSERT_EQ(out.pixel(x, y)[c], in.pixel(x, y)[c]) << x << "," << y;  // far from the edge
      }
    }
    errIn += std::abs(sumIn - exact);
    errOut += std::abs(sumOut - exact);
  }
  std::cout << "mean error of a column's bright share: aliased " << errIn / (w - 32) << " px, filtered "
            << errOut / (w - 32) << " px; " << mixed << " pixels in between\n";
  EXPECT_GT(mixed, (w - 32) / 2);
  EXPECT_LT(errOut, 0.5 * errIn) << "mean error per column: aliased " << errIn / (w - 32) << ", filtered "
                                 << errOut / (w - 32);
}

TEST(Fxaa, LeavesTextAndSmoothSurfacesAlone) {
  const int w = 96, h = 40;
  Image out;
  // Text: the left half is kept as drawn.
  const Image in = lumaFrame(w, h, aboveLine);
  fxaa(in.rgba.data(), w * 4, w, h, out, {PixelRect{0, 0, w / 2, h}});
  int changedRight = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const bool same = std::equal(in.pixel(x, y), in.pixel(x, y) + 3, out.pixel(x, y));
      if (x < w / 2) {
        ASSERT_TRUE(same) << x << "," << y;
      }
      changedRight += !same;
    }
  EXPECT_GT(changedRight, 0);
  // Smooth surfaces (a gridded ground) on both sides of a contrast: left alone.
  const Image smooth = lumaFrame(w, h, aboveLine, [](int, int) { return true; });
  EXPECT_EQ(fxaa(smooth.rgba.data(), w * 4, w, h, out).edgePixels, 0);
  // A body's silhouette against the ground: blended.
  const Image silhouette = lumaFrame(w, h, aboveLine, [](int x, int y) { return !aboveLine(x, y); });
  EXPECT_GT(fxaa(silhouette.rgba.data(), w * 4, w, h, out).edgePixels, w / 2);
}

TEST(Fxaa, ANegativeStrideReadsRowsBottomUp) {
  const Image in = lumaFrame(8, 6, [](int, int y) { return y < 3; });  // bright top half
  Image out;
  // Rows read from the last up: the bright half lands at the bottom.
  copyOpaque(in.rgba.data() + 5 * 8 * 4, -8 * 4, 8, 6, out);
  EXPECT_EQ(out.pixel(0, 0)[0], kDark[0]);
  EXPECT_EQ(out.pixel(0, 5)[0], kBright[0]);
  EXPECT_EQ(out.pixel(0, 5)[3], 255);
  fxaa(in.rgba.data() + 5 * 8 * 4, -8 * 4, 8, 6, out);
  EXPECT_EQ(out.pixel(0, 0)[0], kDark[0]);
  EXPECT_EQ(out.pixel(0, 5)[0], kBright[0]);
}

// The video's filter on the raw frame itself (finishInPlace) blends exactly the pixels, and to
// exactly the colours, that finishFrame's copy does; the rows stay bottom-up, text is kept.
TEST(Fxaa, InPlaceOnTheRawFrameBlendsAsTheCopyDoes) {
  const int w = 96, h = 40;
  const Image drawn = lumaFrame(w, h, aboveLine);
  RawFrame raw;
  raw.width = w;
  raw.height = h;
  raw.keep = {PixelRect{0, 0, w / 4, h}};
  raw.rgba.resize(static_cast<size_t>(w) * h * 4);
  for (int y = 0; y < h; ++y) std::copy_n(drawn.pixel(0, y), 4 * w, &raw.rgba[static_cast<size_t>(h - 1 - y) * w * 4]);
  Image copied;
  const FxaaStats byCopy = finishFrame(raw, copied);
  RawFrame inPlace = raw;
  const FxaaStats byPlace = finishInPlace(inPlace);
  EXPECT_GT(byPlace.edgePixels, w / 2);
  EXPECT_EQ(byPlace.edgePixels, byCopy.edgePixels);
  int changed = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const uint8_t* p = &inPlace.rgba[(static_cast<size_t>(h - 1 - y) * w + x) * 4];
      for (int c = 0; c < 3; ++c) ASSERT_EQ(p[c], copied.pixel(x, y)[c]) << x << "," << y;
      changed += !std::equal(p, p + 3, drawn.pixel(x, y));
      if (x < w / 4) {
        ASSERT_TRUE(std::equal(p, p + 3, drawn.pixel(x, y))) << "text kept at " << x << "," << y;
      }
    }
  EXPECT_GT(changed, 0);
  RawFrame plain = raw;
  plain.fxaa = false;  // no filter asked: left as drawn
  EXPECT_EQ(finishInPlace(plain).edgePixels, 0);
  EXPECT_EQ(plain.rgba, raw.rgba);
}

// ---- text ----

TEST(Text, Utf8AndFontLayout) {
  EXPECT_EQ(decodeUtf8("aκτ≤"), (std::vector<uint32_t>{'a', 0x3BA, 0x3C4, 0x2264}));
  EXPECT_EQ(decodeUtf8("a\xff" "b"), (std::vector<uint32_t>{'a', 0xFFFD, 'b'}));
  EXPECT_EQ(decodeUtf8("\xce"), (std::vector<uint32_t>{0xFFFD}));  // truncated
  const Font f(defaultFontPath(), 20);
  EXPECT_GT(f.width("a"), 5);
  EXPECT_NEAR(f.width("aa"), 2 * f.width("a"), 1e-4);
  EXPECT_GT(f.width("κ=1 τ=0.6"), f.width("k=1 t=0.6") * 0.8);
  EXPECT_EQ(f.layout("a b", 0, 20).size(), 2u);     // a space has no quad
  EXPECT_EQ(f.layout("κτ", 0, 20).size(), 2u);     // Greek is in the atlas
  EXPECT_EQ(f.layout("\xe4\xb8\xad", 0, 20).size(), 0u);  // CJK is not: skipped, not garbage
  const auto q = f.layout("T", 10, 30);
  ASSERT_EQ(q.size(), 1u);
  EXPECT_LT(q[0].y0, 30);  // above the baseline
  EXPECT_GE(q[0].x0, 9);  // a glyph may start a pixel left of the pen (its bearing)
  long coverage = 0;
  for (uint8_t v : f.atlas()) coverage += v;
  EXPECT_GT(coverage, 10000);
  try {
    Font missing("/no/such/font.ttf", 12);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("fonts-dejavu-core"), std::string::npos) << e.what();
  }
}

// ---- video ----

TEST(Video, FramesThroughFfmpegMakeAPlayableFile) {
  const std::string ffmpeg = findFfmpeg();
  if (ffmpeg.empty()) GTEST_SKIP() << "ffmpeg is not installed";
  EXPECT_EQ(findProgram("sh").empty(), false);
  EXPECT_EQ(findProgram("no-such-program-substep"), "");
  const fs::path f = scratch("v.mp4");
  fs::remove(f);
  {
    VideoOptions o;
    o.fps = 30;
    VideoEncoder v(ffmpeg, f.string(), 64, 48, o);
    for (int k = 0; k < 12; ++k) v.write(Image(64, 48, 0x000000ffu | (static_cast<uint32_t>(k * 20) << 24)));
    v.finish();
  }
  ASSERT_TRUE(fs::exists(f));
  const std::string cmd = "ffprobe -v error -count_frames -select_streams v:0 -show_entries "
                          "stream=codec_name,width,height,pix_fmt,nb_read_frames -of csv=p=0 " +
                          f.string() + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  char buf[256] = {0};
  const size_t n = fread(buf, 1, sizeof buf - 1, p);
  pclose(p);
  EXPECT_EQ(std::string(buf, n), "h264,64,48,yuv420p,12\n");
}

TEST(Video, AFailingFfmpegIsReportedAndLeavesNoFile) {
  const fs::path f = scratch("bad.mp4");
  fs::remove(f);
  // /bin/false takes no frames: writing fails with EPIPE (not SIGPIPE), and the message says so.
  bool thrown = false;
  try {
    VideoEncoder v("/bin/false", f.string(), 64, 48, {});
    for (int k = 0; k < 50; ++k) v.write(Image(64, 48));
    v.finish();
  } catch (const VideoError& e) {
    thrown = true;
    EXPECT_NE(std::string(e.what()).find("status 1"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(thrown);
  EXPECT_FALSE(fs::exists(f));
  EXPECT_THROW(VideoEncoder("/bin/true", f.string(), 63, 48, {}), VideoError);  // yuv420p needs even sizes
  // An encoder dropped before finish() removes what it wrote.
  const std::string ffmpeg = findFfmpeg();
  if (ffmpeg.empty()) return;
  {
    VideoEncoder v(ffmpeg, f.string(), 64, 48, {});
    v.write(Image(64, 48));
  }
  EXPECT_FALSE(fs::exists(f));
}

// The conversion to yuv420p: BT.601 at limited range, as ffmpeg's; U and V of each 2x2 block.
TEST(Video, Yuv420IsBt601LimitedRangeAsFfmpegMakesIt) {
  auto yuv = [](uint32_t rgba) {
    std::vector<uint8_t> out;
    rgbaToYuv420(Image(2, 2, rgba), out);
    EXPECT_EQ(out.size(), 6u);
    return std::vector<int>{out[0], out[4], out[5]};
  };
  EXPECT_EQ(yuv(0xffffffffu), (std::vector<int>{235, 128, 128}));
  EXPECT_EQ(yuv(0x000000ffu), (std::vector<int>{16, 128, 128}));
  EXPECT_EQ(yuv(0xff0000ffu), (std::vector<int>{81, 90, 240}));
  EXPECT_EQ(yuv(0x00ff00ffu), (std::vector<int>{145, 54, 34}));
  EXPECT_EQ(yuv(0x0000ffffu), (std::vector<int>{41, 240, 110}));
  // A 4x2 frame: left block red, right block blue; Y per pixel, U and V per block.
  Image img(4, 2, 0xff0000ffu);
  for (int y = 0; y < 2; ++y)
    for (int x = 2; x < 4; ++x) img.pixel(x, y)[0] = 0, img.pixel(x, y)[2] = 255;
  std::vector<uint8_t> out;
  rgbaToYuv420(img, out);
  EXPECT_EQ(out, (std::vector<uint8_t>{81, 81, 41, 41, 81, 81, 41, 41, 90, 240, 240, 110}));
  // A rendered frame, against ffmpeg's own conversion when there is one: the same Y, U and V
  // within 1 level but at a few sharp colour edges (ffmpeg's vertical chroma filter is longer).
  const std::string ffmpeg = findFfmpeg();
  if (ffmpeg.empty()) GTEST_SKIP() << "ffmpeg is not installed";
  const Image frame = readPng(SUBSTEP_SOURCE_DIR "/tests/snapshots/shapes_contacts.png");
  const fs::path raw = scratch("frame.rgba"), converted = scratch("frame.yuv");
  { std::ofstream(raw, std::ios::binary).write(reinterpret_cast<const char*>(frame.rgba.data()), static_cast<std::streamsize>(frame.rgba.size())); }
  const std::string cmd = ffmpeg + " -v error -y -f rawvideo -pix_fmt rgba -s " + std::to_string(frame.width) + "x" +
                          std::to_string(frame.height) + " -i " + raw.string() + " -f rawvideo -pix_fmt yuv420p " +
                          converted.string();
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  std::ifstream in(converted, std::ios::binary);
  const std::vector<uint8_t> theirs((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  rgbaToYuv420(frame, out);
  ASSERT_EQ(theirs.size(), out.size());
  const size_t luma = static_cast<size_t>(frame.width) * frame.height;
  long long chromaOff = 0;
  for (size_t i = 0; i < out.size(); ++i) {
    if (i < luma)
      ASSERT_EQ(out[i], theirs[i]) << "Y at " << i;
    else
      chromaOff += std::abs(int(out[i]) - int(theirs[i])) > 1;
  }
  EXPECT_LT(chromaOff, static_cast<long long>(luma / 2 / 100));  // under 1 % of U and V samples
}

// GL's bottom-up rows read through a negative stride convert as the flipped image does.
TEST(Video, Yuv420ThroughANegativeStrideIsTheFlippedFrames) {
  const Image frame = readPng(SUBSTEP_SOURCE_DIR "/tests/snapshots/shapes_contacts.png");
  const long stride = 4L * frame.width;
  std::vector<uint8_t> bottomUp(frame.rgba.size());
  for (int y = 0; y < frame.height; ++y)
    std::copy_n(frame.pixel(0, y), stride, &bottomUp[static_cast<size_t>(frame.height - 1 - y) * stride]);
  std::vector<uint8_t> expected, got;
  rgbaToYuv420(frame, expected);
  rgbaToYuv420(bottomUp.data() + stride * (frame.height - 1), -stride, frame.width, frame.height, got);
  EXPECT_EQ(got, expected);
}

// ---- frame sinks ----

// Every sink's output appears at commit() and not before; dropped before it, nothing is left.
TEST(FrameSinks, OutputAppearsAtCommitAndNothingIsLeftWithout) {
  using substep_test::listing;
  const fs::path d = substep_test::emptyScratchFolder("test_render_out");
  const Image red(32, 16, 0xff0000ffu), blue(32, 16, 0x0000ffffu);
  {
    PngSink png((d / "one.png").string());
    png.write(red);
    png.write(blue);  // one frame: the last
  }
  {
    PngFolderSink folder((d / "frames/").string());
    folder.write(red);
  }
  EXPECT_TRUE(listing(d).empty()) << listing(d).front();

  PngSink png((d / "one.png").string());
  png.write(red);
  png.write(blue);
  png.commit();
  EXPECT_EQ(readPng((d / "one.png").string()).rgba, blue.rgba);
  EXPECT_THROW(PngSink((d / "none.png").string()).commit(), std::runtime_error);  // no frame

  fs::create_directories(d / "frames");
  { std::ofstream(d / "frames" / "frame_00005.png") << "stale"; }  // of an earlier, longer sequence
  { std::ofstream(d / "frames" / "notes.txt") << "mine"; }
  PngFolderSink folder((d / "frames/").string());
  EXPECT_EQ(PngFolderSink::stagingPath((d / "frames/").string()), (d / "frames").string() + ".part" + std::to_string(getpid()));
  for (const Image* f : {&red, &blue, &red}) folder.write(*f);
  EXPECT_TRUE(fs::is_directory(PngFolderSink::stagingPath((d / "frames").string())));
  EXPECT_EQ(listing(d / "frames"), (std::vector<std::string>{"frame_00005.png", "notes.txt"}));
  folder.commit();
  EXPECT_EQ(listing(d / "frames"), (std::vector<std::string>{"frame_00000.png", "frame_00001.png", "frame_00002.png", "notes.txt"}));
  EXPECT_EQ(readPng((d / "frames" / "frame_00001.png").string()).rgba, blue.rgba);
  EXPECT_EQ(listing(d), (std::vector<std::string>{"frames", "one.png"}));  // no staging folder left

  // A folder sink onto a file is a bad path: OutputError naming it.
  try {
    PngFolderSink onFile((d / "one.png").string());
    FAIL() << "a file is not a folder";
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("one.png: exists and is not a folder"), std::string::npos) << e.what();
  }

  const std::string ffmpeg = findFfmpeg();
  if (ffmpeg.empty()) GTEST_SKIP() << "ffmpeg is not installed: the video sink is not checked";
  {
    VideoSink video(ffmpeg, (d / "v.mp4").string(), 32, 16, {});
    video.write(red);
  }
  EXPECT_FALSE(fs::exists(d / "v.mp4"));
  VideoSink video(ffmpeg, (d / "v.mp4").string(), 32, 16, {});
  for (int k = 0; k < 3; ++k) video.write(k % 2 ? blue : red);
  EXPECT_FALSE(fs::exists(d / "v.mp4"));
  video.commit();
  EXPECT_GT(fs::file_size(d / "v.mp4"), 0u);
  EXPECT_EQ(listing(d), (std::vector<std::string>{"frames", "one.png", "v.mp4"}));
}

// A sink on its own thread writes every frame in order, hands buffers back for reuse, commits
// only when all are written, and leaves nothing when dropped; an error comes out of the next call.
TEST(FrameSinks, AThreadedSinkWritesEveryFrameInOrderBesideTheCaller) {
  using substep_test::listing;
  const fs::path d = substep_test::emptyScratchFolder("test_render_threaded");
  {
    ThreadedSink dropped(std::make_unique<PngFolderSink>((d / "dropped").string()));
    Image f(8, 4, 0x102030ffu);
    dropped.pass(f);
  }
  EXPECT_TRUE(listing(d).empty()) << listing(d).front();

  ThreadedSink sink(std::make_unique<PngFolderSink>((d / "frames").string()), 2);
  Image frame;
  for (int k = 0; k < 6; ++k) {
    if (frame.empty()) frame = Image(8, 4);
    std::fill(frame.rgba.begin(), frame.rgba.end(), static_cast<uint8_t>(40 * k));
    for (size_t i = 3; i < frame.rgba.size(); i += 4) frame.rgba[i] = 255;
    sink.pass(frame);  // frame now holds a spare buffer (empty at first)
  }
  sink.write(Image(8, 4, 0xffffffffu));  // a copy
  sink.commit();
  std::vector<std::string> expected;
  for (int k = 0; k < 7; ++k) expected.push_back(PngFolderSink::frameName(k));
  EXPECT_EQ(listing(d / "frames"), expected);
  for (int k = 0; k < 6; ++k)
    EXPECT_EQ(readPng((d / "frames" / PngFolderSink::frameName(k)).string()).rgba[0], 40 * k) << k;
  EXPECT_GE(sink.writeSeconds(), 0.0);

  // Raw frames (bottom-up, as read back) are finished on the sink's thread: flipped, opaque.
  ThreadedSink rawSink(std::make_unique<PngFolderSink>((d / "raw").string()), 1);
  RawFrame raw;
  raw.width = 4, raw.height = 2, raw.fxaa = false;
  raw.rgba.assign(32, 0);
  for (int x = 0; x < 4; ++x) raw.rgba[4 * x] = 200;  // GL's row 0: the image's bottom row
  rawSink.pass(raw);
  EXPECT_TRUE(raw.rgba.empty());  // no spare yet
  rawSink.commit();
  const Image flipped = readPng((d / "raw" / PngFolderSink::frameName(0)).string());
  EXPECT_EQ(flipped.pixel(0, 1)[0], 200);
  EXPECT_EQ(flipped.pixel(0, 0)[0], 0);
  EXPECT_EQ(flipped.pixel(0, 0)[3], 255);
  EXPECT_GE(rawSink.finishSeconds(), 0.0);

  // The inner sink failing (ffmpeg gone): the error comes out of pass() or commit(), and the
  // output is not left behind.
  {
    ThreadedSink bad(std::make_unique<VideoSink>("/bin/false", (d / "bad.mp4").string(), 64, 48, VideoOptions{}));
    bool thrown = false;
    try {
      for (int k = 0; k < 200; ++k) {
        Image f(64, 48);
        bad.pass(f);
      }
      bad.commit();
    } catch (const VideoError& e) {
      thrown = true;
      EXPECT_NE(std::string(e.what()).find("ffmpeg"), std::string::npos) << e.what();
    }
    EXPECT_TRUE(thrown);
  }
  EXPECT_EQ(listing(d), (std::vector<std::string>{"frames", "raw"}));
}
