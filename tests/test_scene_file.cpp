// Scene files: the asset scenes, every kind of error message, frames and generator geometry.
#include "physics/generators.h"
#include "physics/mass.h"
#include "physics/mesh_loader.h"
#include "physics/scene_file.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <set>
#include <string>

using namespace substep;
namespace fs = std::filesystem;

namespace {

const std::string kSource = SUBSTEP_SOURCE_DIR;
const std::string kScenes = kSource + "/assets/scenes";

// A scene with one dynamic body and whatever else the test needs.
const char* kBall = R"({"name": "ball", "shape": {"type": "sphere", "radius": 0.5}, "position": [0, 2, 0]})";

Scene parse(const std::string& text, const std::string& baseDir = kScenes) { return parseScene(text, "t.json", baseDir); }

// Expects parsing to fail at `path` with a message containing every key word.
void expectError(const std::string& text, const std::string& path, std::initializer_list<std::string> words,
                 const std::string& baseDir = kScenes) {
  try {
    parse(text, baseDir);
    ADD_FAILURE() << "no error for: " << text;
  } catch (const SceneError& e) {
    EXPECT_EQ(e.file, "t.json");
    EXPECT_EQ(e.path, path) << e.what();
    for (const auto& w : words) EXPECT_NE(e.message.find(w), std::string::npos) << "'" << w << "' not in: " << e.what();
    EXPECT_EQ(std::string(e.what()), "t.json: " + path + ": " + e.message);
  }
}

// Scene text around a bodies array and optional extra top-level members.
std::string scene(const std::string& bodies, const std::string& extra = "") {
  return std::string(R"({"bodies": [)") + bodies + "]" + (extra.empty() ? "" : ", " + extra) + "}";
}

std::string ground() {
  return R"({"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [5, 0.5, 5]},
             "position": [0, -0.5, 0]})";
}

Vec3 world(const Scene& s, int body, const Vec3& local) { return s.initial.bodies[body].pose().apply(local); }

void expectVecNear(const Vec3& a, const Vec3& b, double tol) {
  EXPECT_NEAR((a - b).norm(), 0, tol) << "[" << a.transpose() << "] vs [" << b.transpose() << "]";
}

}  // namespace

// ---------------------------------------------------------------- asset scenes

TEST(SceneAssets, AllLoadWithExpectedCounts) {
  struct Expect {
    const char* file;
    int dynamic;
    size_t joints;
  };
  for (const Expect& x : {Expect{"stack.json", 5, 0}, Expect{"box_on_ground.json", 1, 0}, Expect{"pyramid.json", 210, 0},
                          Expect{"pile.json", 1000, 0}, Expect{"pendulum_chain.json", 10, 10},
                          Expect{"chain.json", 30, 30}, Expect{"shapes.json", 5, 0}}) {
    SCOPED_TRACE(x.file);
    const Scene s = loadScene(kScenes + "/" + x.file);
    EXPECT_EQ(s.model.dynamicCount(), x.dynamic);
    EXPECT_EQ(s.model.joints.size(), x.joints);
    EXPECT_EQ(s.initial.bodies.size(), s.model.bodies.size());
    EXPECT_FALSE(s.description.empty());
    ASSERT_FALSE(s.cameras.empty());
    EXPECT_EQ(s.cameras[0].name, "default");
    EXPECT_TRUE(s.solver.algorithm().has_value());
    EXPECT_EQ(s.solver.get(&SolverSettings::dt), 1.0 / 60.0);
    EXPECT_FALSE(s.solver.get(&SolverSettings::iterations).has_value());  // each algorithm's own default applies
    EXPECT_TRUE(s.initial.finite());
    for (const Body& b : s.model.bodies) {
      if (!b.isStatic) {
        EXPECT_GT(b.mass, 0) << b.name;
      }
    }
  }
}

TEST(SceneAssets, StackIsFiveOneKilogramBoxesOnTheGround) {
  const Scene s = loadScene(kScenes + "/stack.json");
  const int g = s.model.bodyIndex("ground");
  ASSERT_GE(g, 0);
  EXPECT_TRUE(s.model.bodies[g].isStatic);
  EXPECT_EQ(s.model.bodies[g].shape.halfExtents, Vec3(10, 0.5, 10));
  EXPECT_NEAR(s.initial.bodies[g].x.y() + 0.5, 0, 1e-15);  // top face at y = 0
  for (int k = 0; k < 5; ++k) {
    const int i = s.model.bodyIndex("stack_" + std::to_string(k));
    ASSERT_GE(i, 0);
    EXPECT_EQ(s.model.bodies[i].mass, 1.0);
    EXPECT_EQ(s.model.bodies[i].friction, 0.8);
    EXPECT_NEAR(s.initial.bodies[i].x.y(), 0.5 + k, 1e-12);
  }
}

TEST(SceneAssets, ChainLinksShareAGroupAndHang) {
  const Scene s = loadScene(kScenes + "/chain.json");
  const int anchor = s.model.bodyIndex("chain_anchor");
  ASSERT_GE(anchor, 0);
  EXPECT_TRUE(s.model.bodies[anchor].isStatic);
  const int group = s.model.bodies[s.model.bodyIndex("chain_0")].group;
  for (int k = 0; k < 30; ++k) EXPECT_EQ(s.model.bodies[s.model.bodyIndex("chain_" + std::to_string(k))].group, group);
  EXPECT_EQ(s.model.joints[0].bodyA, anchor);
  for (const Joint& j : s.model.joints) {
    EXPECT_EQ(j.type, JointType::Ball);
    EXPECT_FALSE(j.collide);
  }
}

TEST(SceneAssets, ShapesHasEveryDynamicShapeOnAMesh) {
  const Scene s = loadScene(kScenes + "/shapes.json");
  std::set<ShapeType> types;
  for (const Body& b : s.model.bodies)
    if (!b.isStatic) types.insert(b.shape.type);
  EXPECT_EQ(types, (std::set<ShapeType>{ShapeType::Sphere, ShapeType::Box, ShapeType::Capsule, ShapeType::Cylinder,
                                        ShapeType::ConvexMesh}));
  const Body& bowl = s.model.bodies[s.model.bodyIndex("bowl")];
  EXPECT_EQ(bowl.shape.type, ShapeType::TriangleMesh);
  ASSERT_TRUE(bowl.shape.mesh);
  EXPECT_LT(bowl.shape.mesh->triangles.size(), 500u);
}

// ---------------------------------------------------------------- errors

TEST(SceneErrors, Syntax) {
  const std::string text = "{\n  \"bodies\": [\n    {\"name\": \"a\",, }\n  ]\n}\n";
  try {
    parse(text);
    FAIL() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.path, "3:18");  // the second comma
    EXPECT_EQ(std::string(e.what()).rfind("t.json:3:18: JSON syntax error: ", 0), 0u) << e.what();
  }
  // Truncated input: the position is the end of the text.
  try {
    parse("{\"bodies\": [\n");
    FAIL() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.path, "2:1") << e.what();
    EXPECT_NE(e.message.find("JSON syntax error"), std::string::npos);
  }
}

TEST(SceneErrors, WrongType) {
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": "1"}})"), "bodies[0].shape.radius",
              {"expected a number in [0.001, 10000], got string"});
  expectError(scene(R"({"name": 5, "shape": {"type": "sphere", "radius": 1}})"), "bodies[0].name",
              {"expected a string, got number"});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "position": [1, 2]})"),
              "bodies[0].position", {"expected an array of 3 numbers", "got an array of 2"});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "position": [1, "2", 3]})"),
              "bodies[0].position[1]", {"expected a number in [-100000, 100000], got string"});
  expectError(scene(kBall, R"("solver": {"warm_start": 1})"), "solver.warm_start", {"expected true or false, got number"});
  expectError(R"({"bodies": {}})", "bodies", {"expected an array, got object"});
  expectError("[]", "(top level)", {"expected an object, got array"});
}

TEST(SceneErrors, MissingField) {
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere"}})"), "bodies[0].shape",
              {"missing required field \"radius\""});
  expectError(scene(R"({"shape": {"type": "sphere", "radius": 1}})"), "bodies[0]", {"missing required field \"name\""});
  expectError(scene(R"({"name": "a"})"), "bodies[0]", {"missing required field \"shape\""});
}

TEST(SceneErrors, UnknownKey) {
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radus": 1}})"), "bodies[0].shape",
              {"unknown key \"radus\" (expected one of: type, radius)"});
  expectError(scene(kBall, R"("gravty": [0, -9.81, 0])"), "(top level)", {"unknown key \"gravty\""});
  expectError(scene(kBall, R"("solver": {"iteration": 5})"), "solver", {"unknown key \"iteration\"", "iterations"});
  // Keys valid for one type are unknown for another: limits on a ball joint.
  expectError(scene(std::string(kBall) + ", " + ground(),
                    R"("joints": [{"type": "ball", "bodies": ["ball", "ground"], "anchor": [0, 0, 0], "limits": [0, 1]}])"),
              "joints[0]", {"unknown key \"limits\""});
  expectError(R"({"bodies": [{"name": "a", "shape": {"type": "sphere", "radius": 1}, "name": "b"}]})", "bodies[0]",
              {"duplicate key \"name\""});
}

TEST(SceneErrors, BadNumbers) {
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "mass": -1})"), "bodies[0].mass",
              {"expected a number in [1e-6, 1e9], got -1"});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "density": 0})"), "bodies[0].density",
              {"expected a number in [0.001, 1000000], got 0"});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "mass": 1, "density": 2})"),
              "bodies[0].density", {"either \"mass\" or \"density\""});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "restitution": 1.5})"),
              "bodies[0].restitution", {"in [0, 1]", "1.5"});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "orientation": [0, 0, 0, 0]})"),
              "bodies[0].orientation", {"non-zero quaternion"});
  expectError(scene(kBall, R"("solver": {"dt": 0})"), "solver.dt", {"in [1e-6, 1]", "got 0"});
  expectError(scene(kBall, R"("solver": {"omega": 2})"), "solver.omega", {"in (0, 2)"});
  expectError(scene(kBall, R"("solver": {"iterations": 2.5})"), "solver.iterations", {"an integer in [1, 100000]", "2.5"});
  expectError(scene(kBall, R"("solver": {"algorithm": "a9"})"), "solver.algorithm", {"a1, a2, a3, a4, a5", "\"a9\""});
}

TEST(SceneErrors, ZeroSizeShape) {
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 0}})"), "bodies[0].shape.radius",
              {"expected a number in [0.001, 10000], got 0"});
  expectError(scene(R"({"name": "a", "shape": {"type": "box", "half_extents": [1, 0, 1]}})"),
              "bodies[0].shape.half_extents[1]", {"expected a number in [0.001, 10000], got 0"});
  expectError(scene(R"({"name": "a", "shape": {"type": "capsule", "radius": 0.2, "half_height": -0.1}})"),
              "bodies[0].shape.half_height", {"in [0.001, 10000]", "-0.1"});
  expectError(scene(R"({"name": "a", "shape": {"type": "convex", "file": "../meshes/gem.obj", "scale": 0}})"),
              "bodies[0].shape.scale", {"in [0.001, 1000]"});
}

TEST(SceneErrors, UnknownTypes) {
  expectError(scene(std::string(kBall) + ", " + ground(),
                    R"("joints": [{"type": "slider", "bodies": ["ball", "ground"], "anchor": [0, 0, 0]}])"),
              "joints[0].type",
              {"unknown joint type \"slider\"", "ball, hinge, cone_twist, fixed, spring, motor"});
  expectError(scene(R"({"name": "a", "shape": {"type": "cone", "radius": 1}})"), "bodies[0].shape.type",
              {"unknown shape type \"cone\"", "sphere, box, capsule, cylinder, convex, plane, mesh"});
  expectError(scene(kBall, R"("generators": [{"type": "tower"}])"), "generators[0].type",
              {"unknown generator type \"tower\"", "stack, pyramid, chain"});
}

TEST(SceneErrors, DuplicateName) {
  expectError(scene(std::string(kBall) + ", " + kBall), "bodies[1].name",
              {"duplicate body name \"ball\"", "bodies[0]"});
  // A generated name that clashes with a body.
  expectError(scene(R"({"name": "s_1", "static": true, "shape": {"type": "sphere", "radius": 1}, "position": [9, 0, 0]})",
                    R"("generators": [{"type": "stack", "name": "s", "count": 3, "half_extents": [0.5, 0.5, 0.5]}])"),
              "generators[0].name", {"duplicate body name \"s_1\"", "bodies[0]"});
}

TEST(SceneErrors, JointBodies) {
  const std::string bodies = std::string(kBall) + ", " + ground();
  expectError(scene(bodies, R"("joints": [{"type": "ball", "bodies": ["ball", "nope"], "anchor": [0, 0, 0]}])"),
              "joints[0].bodies[1]", {"unknown body \"nope\""});
  expectError(scene(bodies, R"("joints": [{"type": "ball", "bodies": ["ball", "ball"], "anchor": [0, 0, 0]}])"),
              "joints[0].bodies", {"two different bodies"});
  expectError(scene(bodies + R"(, {"name": "g2", "static": true, "shape": {"type": "sphere", "radius": 1}})",
                    R"("joints": [{"type": "ball", "bodies": ["ground", "g2"], "anchor": [0, 0, 0]}])"),
              "joints[0].bodies", {"both bodies are static"});
  expectError(scene(bodies, R"("joints": [{"type": "hinge", "bodies": ["ball", "ground"], "anchor": [0, 0, 0]}])"),
              "joints[0]", {"missing required field \"axis\""});
  expectError(scene(bodies, R"("joints": [{"type": "hinge", "bodies": ["ball", "ground"], "anchor": [0, 0, 0],
                                             "axis": [0, 0, 1], "limits": [1, -1]}])"),
              "joints[0].limits", {"lower <= upper"});
}

TEST(SceneErrors, StaticBodies) {
  expectError(scene(std::string(kBall) + R"(, {"name": "g", "static": true, "mass": 3,
                                              "shape": {"type": "sphere", "radius": 1}})"),
              "bodies[1].mass", {"static bodies take no mass"});
  expectError(scene(std::string(kBall) + R"(, {"name": "g", "static": true, "velocity": [1, 0, 0],
                                              "shape": {"type": "sphere", "radius": 1}})"),
              "bodies[1].velocity", {"static bodies take no mass"});
  expectError(scene(R"({"name": "floor", "shape": {"type": "plane"}})"), "bodies[0].shape.type",
              {"only be static"});
  expectError(scene(ground()), "(top level)", {"at least one dynamic body"});
  expectError("{}", "(top level)", {"at least one dynamic body"});
}

TEST(SceneErrors, Meshes) {
  expectError(scene(R"({"name": "a", "shape": {"type": "convex", "file": "no_such.obj"}})"), "bodies[0].shape.file",
              {"cannot load mesh", "no_such.obj", "No such file"});

  // Faces wound inwards: negative volume.
  const fs::path dir = fs::temp_directory_path() / "substep_test_scene_file";
  fs::create_directories(dir);
  {
    std::ofstream f(dir / "inside_out.obj");
    f << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n";  // wrong way round
    std::ofstream g(dir / "tetra.obj");
    g << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
  }
  expectError(scene(R"({"name": "a", "shape": {"type": "convex", "file": "inside_out.obj"}})"), "bodies[0].shape.file",
              {"volume", "expected > 0"}, dir.string());
  // The right way round loads, with its mass from the tetrahedron's volume 1/6.
  const Scene s = parse(scene(R"({"name": "a", "shape": {"type": "convex", "file": "tetra.obj", "scale": 2},
                                  "density": 3})"),
                        dir.string());
  EXPECT_NEAR(s.model.bodies[0].mass, 3.0 * 8.0 / 6.0, 1e-12);
}

TEST(SceneErrors, Files) {
  try {
    loadScene("/nonexistent/dir/x.json");
    FAIL() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), "/nonexistent/dir/x.json: cannot open: No such file or directory");
  }
  // Every fixture in tests/data/bad fails, naming its file.
  int n = 0;
  for (const auto& entry : fs::directory_iterator(kSource + "/tests/data/bad")) {
    if (entry.path().extension() != ".json") continue;
    ++n;
    try {
      loadScene(entry.path().string());
      ADD_FAILURE() << entry.path() << " loaded";
    } catch (const SceneError& e) {
      EXPECT_EQ(e.file, entry.path().string());
      EXPECT_EQ(std::string(e.what()).rfind(entry.path().string() + ":", 0), 0u) << e.what();
    }
  }
  EXPECT_GE(n, 3);
  try {
    loadScene(kSource + "/tests/data/bad/syntax.json");
  } catch (const SceneError& e) {
    EXPECT_EQ(e.path, "4:5") << e.what();
  }
}

// Every setting of the table is read from a scene's solver block under its key, and a value
// outside its range is refused with the table's words: the command line says the same
// (test_cli.cpp, SolverOptionsUseTheTable).
TEST(SceneErrors, SolverSettingsComeFromTheTable) {
  for (const SettingSpec& spec : settingTable()) {
    const std::string key = spec.key;
    std::string good, bad;
    switch (spec.kind) {
      case SettingKind::Integer: good = numberText(spec.range.lo); bad = numberText(spec.range.hi + 1); break;
      case SettingKind::Real: good = numberText(spec.range.hi / 2); bad = numberText(spec.range.hi * 2 + 1); break;
      case SettingKind::Flag: good = "true"; bad = "\"on\""; break;
      case SettingKind::Choice: good = "\"" + spec.choices.back() + "\""; bad = "\"nonsense\""; break;
    }
    std::string extra = "\"solver\": {\"" + key + "\": " + good + "}";
    const Scene ok = parse(scene(kBall, extra));
    EXPECT_TRUE(ok.solver.has(spec)) << key;
    extra = "\"solver\": {\"" + key + "\": " + bad + "}";
    const std::string expected = spec.kind == SettingKind::Flag ? "true or false" : spec.expected();
    expectError(scene(kBall, extra), "solver." + key, {"expected " + expected});
  }
}

// Every number in a scene has a physical range (physics/limits.h); beyond it the value is refused
// with its path, before anything is built from it.
TEST(SceneErrors, PhysicalRanges) {
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 2e4}})"), "bodies[0].shape.radius",
              {"in [0.001, 10000]", "20000"});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "angular_velocity": [0, 0, 2e4]})"),
              "bodies[0].angular_velocity[2]", {"in [-10000, 10000]"});
  expectError(scene(kBall, R"("gravity": [0, -2000, 0])"), "gravity[1]", {"in [-1000, 1000]"});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "friction": 11})"), "bodies[0].friction",
              {"in [0, 10]"});
  // A mass from a density is a mass: a 1 mm ball of air weighs 5e-9 kg.
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 0.001}, "density": 1.2})"),
              "bodies[0].density", {"weighs", "expected a body mass in [1e-6, 1e9] kg"});
  expectError(scene(kBall, R"("cameras": [{"name": "c", "distance": 1e9}])"), "cameras[0].distance", {"in [0.001, 100000]"});
  expectError(scene(kBall, R"("cameras": [{"name": "c", "yaw": 1e300}])"), "cameras[0].yaw", {"in [-100000, 100000]"});
  // What generators make must be in range too, though each parameter is.
  expectError(scene(kBall, R"("generators": [{"type": "stack", "count": 300, "mass": 1, "half_extents": [500, 500, 500]}])"),
              "generators[0]", {"generated body", "expected every coordinate in [-100000, 100000]"});
  // Joint limits and motors.
  expectError(scene(kBall + std::string(R"(, {"name": "b", "shape": {"type": "sphere", "radius": 0.5}})"),
                    R"("joints": [{"type": "hinge", "bodies": ["ball", "b"], "anchor": [0, 1, 0], "axis": [1, 0, 0],
                                  "motor": {"speed": 1e5}}])"),
              "joints[0].motor.speed", {"in [-10000, 10000]"});
}

// The cap on bodies (and joints) of a whole scene, raised by SceneLimits (--max-bodies).
TEST(SceneErrors, BodyCap) {
  const std::string pyramid = R"("generators": [{"type": "pyramid", "levels": 20, "half_extents": [0.5, 0.5, 0.5]}])";
  SceneLimits lim;
  lim.maxBodies = 200;
  try {
    parseScene(scene(kBall, pyramid), "t.json", kScenes, lim);
    ADD_FAILURE() << "210 boxes accepted under a cap of 200";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.path, "generators[0].levels");
    EXPECT_NE(e.message.find("20 levels make 210 bodies, 211 with those before: more than the limit of 200"),
              std::string::npos)
        << e.what();
  }
  lim.maxBodies = 211;
  EXPECT_EQ(parseScene(scene(kBall, pyramid), "t.json", kScenes, lim).model.bodies.size(), 211u);
  lim.maxBodies = 3;
  try {
    parseScene(scene(kBall + std::string(",") + kBall + "," + kBall + "," + kBall), "t.json", kScenes, lim);
    ADD_FAILURE() << "4 bodies accepted under a cap of 3";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.path, "bodies");
  }
}

// The text itself: numbers beyond a double, nesting, names, duplicate keys deep inside, NUL.
TEST(SceneErrors, HostileText) {
  try {
    parse("{\"bodies\": [\n  {\"name\": \"a\", \"mass\": -1e999}]}");
    ADD_FAILURE();
  } catch (const SceneError& e) {
    EXPECT_EQ(e.path, "2:30") << e.what();  // line and column of the number
    EXPECT_NE(e.message.find("\"-1e999\" is beyond the range of a double"), std::string::npos) << e.what();
  }
  try {
    parse(std::string(100000, '[') + std::string(100000, ']'));
    ADD_FAILURE();
  } catch (const SceneError& e) {
    EXPECT_NE(e.message.find("nested more than 64 deep"), std::string::npos) << e.what();
    EXPECT_LT(std::string(e.what()).size(), 500u);
  }
  expectError(scene(R"({"name": "a\nb", "shape": {"type": "sphere", "radius": 1}})"), "bodies[0].name",
              {"control character", "\"a\\x0ab\""});
  expectError(scene(R"({"name": ")" + std::string(300, 'x') + R"(", "shape": {"type": "sphere", "radius": 1}})"),
              "bodies[0].name", {"300 bytes; expected at most 256"});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1, "radius": 2}})"), "bodies[0].shape",
              {"duplicate key \"radius\""});
  // A key a megabyte long is quoted, not printed whole.
  try {
    parse(scene(kBall, "\"" + std::string(1 << 20, 'k') + "\": 1"));
    ADD_FAILURE();
  } catch (const SceneError& e) {
    EXPECT_LT(std::string(e.what()).size(), 1000u);
  }
}

TEST(SceneErrors, InputFilesMustBeRegular) {
  EXPECT_EQ(checkInputFile("/dev/zero", 100), "not a regular file (a pipe, device or socket); give a file");
  EXPECT_EQ(checkInputFile(std::string("a\0b", 3), 100), "the path holds a NUL character");
  EXPECT_EQ(checkInputFile(kScenes + "/stack.json", 10).rfind("the file is ", 0), 0u);
  EXPECT_EQ(checkInputFile(kScenes + "/stack.json", 1 << 20), "");
  std::string text;
  EXPECT_EQ(checkInputFile(kScenes + "/stack.json", 1 << 20, &text), "");
  EXPECT_NE(text.find("\"bodies\""), std::string::npos);
}

// Convex meshes must be closed; vertices no triangle uses are dropped.
TEST(SceneErrors, ConvexMeshesMustBeClosed) {
  expectError(scene(R"({"name": "a", "shape": {"type": "convex", "file": "open_box.obj"}})"), "bodies[0].shape.file",
              {"not a closed surface", "4 edges border one triangle only", "convex-hull"}, kSource + "/tests/data/meshes");
  Mesh m = loadMesh(kSource + "/assets/meshes/gem.obj");
  EXPECT_EQ(closedSurfaceProblem(m), "");
  m.triangles.pop_back();
  EXPECT_NE(closedSurfaceProblem(m).find("3 edges border one triangle only"), std::string::npos)
      << closedSurfaceProblem(m);
}

// ---------------------------------------------------------------- frames and defaults

TEST(SceneFrames, DefaultsAndOrientation) {
  const Scene s = parse(scene(R"({"name": "a", "shape": {"type": "box", "half_extents": [1, 1, 1]},
                                  "orientation": [2, 0, 0, 0]})"));
  const Body& b = s.model.bodies[0];
  EXPECT_EQ(s.model.gravity, Vec3(0, -9.81, 0));
  EXPECT_EQ(b.friction, 0.5);
  EXPECT_EQ(b.restitution, 0);
  EXPECT_EQ(b.group, -1);
  EXPECT_NEAR(b.mass, 8000, 1e-9);  // density 1000
  EXPECT_NEAR(angleBetween(s.initial.bodies[0].q, Quat::Identity()), 0, 1e-15);
  EXPECT_FALSE(s.solver.algorithm().has_value());
  EXPECT_TRUE(s.cameras.empty());
}

TEST(SceneFrames, AngularVelocityIsConvertedToTheBodyFrame) {
  // 90 degrees about Z: the body's -Y axis is the world's X axis.
  const double c = std::sqrt(0.5);
  const Scene s = parse(scene(R"({"name": "a", "shape": {"type": "box", "half_extents": [1, 2, 3]},
      "orientation": [)" + std::to_string(c) + ", 0, 0, " + std::to_string(c) +
                              R"(], "angular_velocity": [1, 0, 0], "velocity": [0, 0, 4]})"));
  const BodyState& st = s.initial.bodies[0];
  expectVecNear(st.w, Vec3(0, -1, 0), 1e-6);
  expectVecNear(st.worldAngularVelocity(), Vec3(1, 0, 0), 1e-12);
  expectVecNear(st.v, Vec3(0, 0, 4), 0);
}

TEST(SceneFrames, ConvexMeshBodyFrameIsPrincipal) {
  // The scene's pose is the mesh file's; the body's is the principal frame: bodyPose = filePose ∘ principal.
  const Scene s = parse(scene(R"({"name": "gem", "shape": {"type": "convex", "file": "../meshes/gem.obj", "scale": 2},
      "position": [1, 2, 3], "orientation": [0.9, 0.1, -0.3, 0.2], "angular_velocity": [0, 0, 5]})"));
  const Body& b = s.model.bodies[0];
  const BodyState& st = s.initial.bodies[0];
  Pose file;
  file.p = Vec3(1, 2, 3);
  file.q = Quat(0.9, 0.1, -0.3, 0.2).normalized();
  const Mesh raw = loadMesh(kSource + "/assets/meshes/gem.obj", 2);
  ASSERT_EQ(raw.vertices.size(), b.shape.mesh->vertices.size());
  for (size_t i = 0; i < raw.vertices.size(); ++i)
    expectVecNear(st.pose().apply(b.shape.mesh->vertices[i]), file.apply(raw.vertices[i]), 1e-12);
  // The body frame is principal: the centre of mass at its origin, the inertia diagonal.
  const MassProperties mp = meshMassProperties(*b.shape.mesh, 1000);
  EXPECT_NEAR(mp.com.norm(), 0, 1e-12);
  EXPECT_NEAR(b.mass, mp.mass, 1e-9);
  EXPECT_NEAR((b.inertia - mp.inertia.diagonal()).norm(), 0, 1e-9);
  EXPECT_NEAR(std::abs(mp.inertia(0, 1)) + std::abs(mp.inertia(0, 2)) + std::abs(mp.inertia(1, 2)), 0, 1e-9);
  EXPECT_EQ(b.shape.scale, 2);
  expectVecNear(st.worldAngularVelocity(), Vec3(0, 0, 5), 1e-12);
}

TEST(SceneFrames, SolverAndCameras) {
  const Scene s = parse(scene(kBall, R"("solver": {"algorithm": "a4", "dt": 0.01, "substeps": 8, "iterations": 2,
      "omega": 1.3, "tolerance": 0, "kappa": 1.1, "tau": 0.9, "slop": 0.01, "warm_start": true, "block_solve": false,
      "preset": "4-medium"}, "gravity": [0, 0, -1],
      "cameras": [{"name": "default", "target": [1, 2, 3], "yaw": -10, "pitch": 45, "distance": 7, "fov": 60,
                   "follow": "ball"}, {"name": "top"}])"));
  EXPECT_EQ(s.solver.algorithm(), Algorithm::A4);
  EXPECT_EQ(s.solver.get(&SolverSettings::dt), 0.01);
  EXPECT_EQ(s.solver.get(&SolverSettings::substeps), 8);
  EXPECT_EQ(s.solver.get(&SolverSettings::iterations), 2);
  EXPECT_EQ(s.solver.get(&SolverSettings::omega), 1.3);
  EXPECT_EQ(s.solver.get(&SolverSettings::tolerance), 0.0);
  EXPECT_EQ(s.solver.get(&SolverSettings::kappa), 1.1);
  EXPECT_EQ(s.solver.get(&SolverSettings::tau), 0.9);
  EXPECT_EQ(s.solver.get(&SolverSettings::slop), 0.01);
  EXPECT_EQ(s.solver.get(&SolverSettings::warmStart), true);
  EXPECT_EQ(s.solver.get(&SolverSettings::blockSolve), false);
  EXPECT_EQ(s.solver.preset(), "4-medium");
  EXPECT_EQ(s.model.gravity, Vec3(0, 0, -1));
  ASSERT_EQ(s.cameras.size(), 2u);
  EXPECT_EQ(s.cameras[0].target, Vec3(1, 2, 3));
  EXPECT_EQ(s.cameras[0].yaw, -10);
  EXPECT_EQ(s.cameras[0].pitch, 45);
  EXPECT_EQ(s.cameras[0].distance, 7);
  EXPECT_EQ(s.cameras[0].fovY, 60);
  EXPECT_EQ(s.cameras[0].follow, "ball");
  EXPECT_EQ(s.cameras[1].distance, CameraPreset().distance);
  expectError(scene(kBall, R"("cameras": [{"name": "c", "follow": "nobody"}])"), "cameras[0].follow",
              {"unknown body \"nobody\""});
  expectError(scene(kBall, R"("cameras": [{"target": [0, 0, 0]}])"), "cameras[0]", {"missing required field \"name\""});
}

TEST(SceneFrames, ExplicitJointsStoreMatchingFrames) {
  const Scene s = parse(scene(
      R"({"name": "a", "shape": {"type": "box", "half_extents": [0.5, 0.5, 0.5]}, "position": [0, 1, 0],
          "orientation": [0.9, 0.3, 0.1, 0]},
         {"name": "b", "shape": {"type": "capsule", "radius": 0.2, "half_height": 0.5}, "position": [1.5, 1, 0.2],
          "orientation": [0.5, 0.5, -0.5, 0.5]})",
      R"("joints": [{"type": "hinge", "name": "h", "bodies": ["a", "b"], "anchor": [0.75, 1, 0.1],
                     "axis": [0, 0, 2], "limits": [-0.5, 0.25], "motor": {"speed": 2}, "collide": true},
                    {"type": "cone_twist", "bodies": ["a", "b"], "anchor": [0.75, 1, 0.1], "axis": [1, 0, 0],
                     "swing": 0.4},
                    {"type": "spring", "bodies": ["a", "b"], "anchors": [[0, 1.5, 0], [1.5, 1.5, 0.2]]},
                    {"type": "fixed", "bodies": ["a", "b"], "anchor": [0.75, 1, 0.1]}])"));
  ASSERT_EQ(s.model.joints.size(), 4u);
  const Joint& h = s.model.joints[0];
  EXPECT_EQ(h.name, "h");
  EXPECT_EQ(h.type, JointType::Hinge);
  EXPECT_EQ(h.bodyA, 0);
  EXPECT_EQ(h.bodyB, 1);
  EXPECT_TRUE(h.collide);
  EXPECT_TRUE(h.hasLimits);
  EXPECT_EQ(h.lower, -0.5);
  EXPECT_EQ(h.upper, 0.25);
  EXPECT_TRUE(h.hasMotor);
  EXPECT_EQ(h.motorSpeed, 2);
  EXPECT_EQ(h.motorMaxTorque, 0);
  for (const Joint& j : s.model.joints) {
    SCOPED_TRACE(jointTypeName(j.type));
    const Quat& qa = s.initial.bodies[j.bodyA].q;
    const Quat& qb = s.initial.bodies[j.bodyB].q;
    if (j.type != JointType::Spring) expectVecNear(world(s, 0, j.localAnchorA), world(s, 1, j.localAnchorB), 1e-12);
    expectVecNear(qa * j.localAxisA, qb * j.localAxisB, 1e-12);
    expectVecNear(qa * j.localRefA, qb * j.localRefB, 1e-12);
    EXPECT_NEAR(j.localAxisA.norm(), 1, 1e-12);
    EXPECT_NEAR(j.localRefA.norm(), 1, 1e-12);
    EXPECT_NEAR(j.localAxisA.dot(j.localRefA), 0, 1e-12);
    EXPECT_NEAR(j.localAxisB.dot(j.localRefB), 0, 1e-12);
  }
  expectVecNear(s.initial.bodies[0].q * h.localAxisA, Vec3(0, 0, 1), 1e-12);
  expectVecNear(world(s, 0, h.localAnchorA), Vec3(0.75, 1, 0.1), 1e-12);
  EXPECT_EQ(s.model.joints[1].swing, 0.4);
  const Joint& sp = s.model.joints[2];
  expectVecNear(world(s, 0, sp.localAnchorA), Vec3(0, 1.5, 0), 1e-12);
  expectVecNear(world(s, 1, sp.localAnchorB), Vec3(1.5, 1.5, 0.2), 1e-12);
  EXPECT_NEAR(sp.restLength, std::sqrt(1.5 * 1.5 + 0.2 * 0.2), 1e-12);
  EXPECT_FALSE(sp.collide);
}

// ---------------------------------------------------------------- generators

TEST(Generators, StackBoxesTouchAcrossTheGap) {
  const Scene s = parse(scene(kBall, R"("generators": [{"type": "stack", "count": 4, "half_extents": [0.5, 0.3, 0.4],
      "position": [1, 2, 3], "gap": 0.25, "density": 10, "friction": 0.9}])"));
  ASSERT_EQ(s.model.bodies.size(), 5u);
  double below = 2.0 - 0.25;  // so that the first box's bottom is the position
  for (int k = 0; k < 4; ++k) {
    const int i = s.model.bodyIndex("stack0_" + std::to_string(k));
    ASSERT_EQ(i, k + 1);
    const Body& b = s.model.bodies[i];
    const Vec3 x = s.initial.bodies[i].x;
    EXPECT_NEAR(x.x(), 1, 0);
    EXPECT_NEAR(x.z(), 3, 0);
    EXPECT_NEAR((x.y() - 0.3) - below, 0.25, 1e-12) << "box " << k;  // bottom face to the box below's top
    below = x.y() + 0.3;
    EXPECT_EQ(b.group, 0);  // the generator's index
    EXPECT_EQ(b.friction, 0.9);
    EXPECT_NEAR(b.mass, 10 * 1 * 0.6 * 0.8, 1e-12);
  }
}

TEST(Generators, PyramidPositions) {
  const Scene s = parse(scene(kBall, R"("generators": [{"type": "stack", "count": 1, "half_extents": [1, 1, 1],
      "position": [20, 0, 0]}, {"type": "pyramid", "name": "p", "levels": 3, "half_extents": [0.5, 0.5, 0.5],
      "position": [0, 1, -2], "gap": 0.1, "mass": 2}])"));
  ASSERT_EQ(s.model.dynamicCount(), 1 + 1 + 6);
  const auto at = [&](const std::string& n) {
    const int i = s.model.bodyIndex(n);
    EXPECT_GE(i, 0) << n;
    return i < 0 ? Vec3(NAN, NAN, NAN) : s.initial.bodies[i].x;
  };
  expectVecNear(at("p_0_0"), Vec3(-1.1, 1.5, -2), 1e-12);
  expectVecNear(at("p_0_1"), Vec3(0, 1.5, -2), 1e-12);
  expectVecNear(at("p_0_2"), Vec3(1.1, 1.5, -2), 1e-12);
  expectVecNear(at("p_1_0"), Vec3(-0.55, 2.5, -2), 1e-12);
  expectVecNear(at("p_1_1"), Vec3(0.55, 2.5, -2), 1e-12);
  expectVecNear(at("p_2_0"), Vec3(0, 3.5, -2), 1e-12);
  EXPECT_EQ(s.model.bodies[s.model.bodyIndex("p_2_0")].group, 1);
  EXPECT_EQ(s.model.bodies[s.model.bodyIndex("p_2_0")].mass, 2);

  Scene big;
  PyramidParams p;
  p.levels = 20;
  addPyramid(big, p);
  EXPECT_EQ(big.model.dynamicCount(), 210);
  EXPECT_EQ(big.initial.bodies.size(), 210u);
}

TEST(Generators, ChainJointAnchorsCoincide) {
  for (const char* joint : {"ball", "hinge"}) {
    SCOPED_TRACE(joint);
    const Scene s = parse(scene(kBall, std::string(R"("generators": [{"type": "chain", "name": "c", "count": 6,
        "link": {"type": "capsule", "radius": 0.05, "half_height": 0.2}, "anchor": [1, 5, -1],
        "direction": [0, -3, 4], "spacing": 0.5, "mass": 0.7, "group": 9, "joint": ")") +
                                    joint + "\"}]"));
    ASSERT_EQ(s.model.joints.size(), 6u);
    const Vec3 d = Vec3(0, -3, 4) / 5;
    const int anchor = s.model.bodyIndex("c_anchor");
    ASSERT_GE(anchor, 0);
    EXPECT_TRUE(s.model.bodies[anchor].isStatic);
    EXPECT_EQ(s.model.bodies[anchor].shape.type, ShapeType::Sphere);
    EXPECT_EQ(s.model.bodies[anchor].shape.radius, 0.05);
    expectVecNear(s.initial.bodies[anchor].x, Vec3(1, 5, -1), 0);
    for (int k = 0; k < 6; ++k) {
      const Joint& j = s.model.joints[k];
      const int link = s.model.bodyIndex("c_" + std::to_string(k));
      EXPECT_EQ(j.bodyA, k == 0 ? anchor : s.model.bodyIndex("c_" + std::to_string(k - 1)));
      EXPECT_EQ(j.bodyB, link);
      EXPECT_EQ(j.type, std::string(joint) == "ball" ? JointType::Ball : JointType::Hinge);
      EXPECT_FALSE(j.collide);
      const Vec3 pivot = Vec3(1, 5, -1) + k * 0.5 * d;
      expectVecNear(world(s, j.bodyA, j.localAnchorA), pivot, 1e-12);
      expectVecNear(world(s, j.bodyB, j.localAnchorB), pivot, 1e-12);
      expectVecNear(s.initial.bodies[j.bodyA].q * j.localAxisA, s.initial.bodies[j.bodyB].q * j.localAxisB, 1e-12);
      // The link's centre half a spacing on, its axis (local Y) along the chain.
      expectVecNear(s.initial.bodies[link].x, Vec3(1, 5, -1) + (k + 0.5) * 0.5 * d, 1e-12);
      expectVecNear(s.initial.bodies[link].q * Vec3::UnitY(), d, 1e-12);
      EXPECT_EQ(s.model.bodies[link].group, 9);
      EXPECT_NEAR(s.model.bodies[link].mass, 0.7, 1e-15);
    }
    if (std::string(joint) == "hinge") {
      const Vec3 axis = s.initial.bodies[s.model.joints[0].bodyB].q * s.model.joints[0].localAxisB;
      EXPECT_NEAR(axis.dot(d), 0, 1e-12);
      EXPECT_NEAR(axis.y(), 0, 1e-12);  // horizontal
    }
  }
  expectError(scene(kBall, R"("generators": [{"type": "chain", "count": 2, "link": {"type": "cylinder", "radius": 0.1,
      "half_height": 0.2}, "anchor": [0, 0, 0], "spacing": 0.5}])"),
              "generators[0].link.type", {"capsule, box or sphere", "cylinder"});
  expectError(scene(kBall, R"("generators": [{"type": "chain", "count": 0, "link": {"type": "sphere", "radius": 0.1},
      "anchor": [0, 0, 0], "spacing": 0.5}])"),
              "generators[0].count", {"an integer in [1, 1000000], got 0"});
  expectError(scene(kBall, R"("generators": [{"type": "stack", "count": 2, "half_extents": [0.5, 0.5, 0.5],
      "spacing": 1}])"),
              "generators[0]", {"unknown key \"spacing\""});
}

TEST(Generators, ListNamesEveryType) {
  std::set<std::string> types;
  for (const GeneratorInfo& g : generatorList()) {
    types.insert(g.type);
    EXPECT_FALSE(g.summary.empty());
    EXPECT_EQ(g.summary.find('\n'), std::string::npos);
  }
  EXPECT_EQ(types, (std::set<std::string>{"stack", "pyramid", "chain", "ragdoll"}));
}

// A ragdoll: 14 bodies of an adult's masses (68 kg, pelvis to forearm 10:1), 13 joints whose
// anchors coincide on both bodies, every joint limited; layers of columns as documented.
TEST(Generators, RagdollBodiesJointsAndLayout) {
  const Scene s = parseScene(R"({"bodies": [], "generators": [{"type": "ragdoll", "name": "r", "count": 6,
      "columns": 3, "position": [1, 2, 3], "offset": [0, 0.5, 0], "spread": [0.8, 0, 0], "yaw": 1.5707963267948966}]})",
                             "<ragdoll>", ".");
  ASSERT_EQ(s.model.bodies.size(), 6u * ragdollParts().size());
  EXPECT_EQ(ragdollParts().size(), 14u);
  ASSERT_EQ(s.model.joints.size(), 6u * 13u);
  double total = 0;
  for (size_t i = 0; i < ragdollParts().size(); ++i) total += s.model.bodies[i].mass;
  EXPECT_NEAR(total, 68.0, 1e-9);
  const int pelvis = s.model.bodyIndex("r_0_pelvis"), forearm = s.model.bodyIndex("r_0_forearm_l");
  ASSERT_GE(pelvis, 0);
  ASSERT_GE(forearm, 0);
  EXPECT_NEAR(s.model.bodies[static_cast<size_t>(pelvis)].mass / s.model.bodies[static_cast<size_t>(forearm)].mass, 10.0,
              1e-9);
  for (const Joint& j : s.model.joints) {
    EXPECT_TRUE(j.hasLimits) << j.name;
    EXPECT_LT((s.initial.bodies[static_cast<size_t>(j.bodyA)].pose().apply(j.localAnchorA) -
               s.initial.bodies[static_cast<size_t>(j.bodyB)].pose().apply(j.localAnchorB))
                  .norm(),
              1e-12)
        << j.name;
    EXPECT_NE(s.model.bodies[static_cast<size_t>(j.bodyA)].group, -1);
  }
  // Column 1 of layer 0 is at the position; layer 1 is 0.5 higher and turned a quarter.
  const Vec3 p01 = s.initial.bodies[static_cast<size_t>(s.model.bodyIndex("r_1_pelvis"))].x;
  EXPECT_LT((p01 - Vec3(1, 2, 3)).norm(), 1e-12);
  const Vec3 p10 = s.initial.bodies[static_cast<size_t>(s.model.bodyIndex("r_3_pelvis"))].x;
  EXPECT_LT((p10 - Vec3(1, 2.5, 3.8)).norm(), 1e-9);  // Ry(90°) turns -0.8 x into +0.8 z
  // Each ragdoll is its own group.
  EXPECT_NE(s.model.bodies[static_cast<size_t>(pelvis)].group,
            s.model.bodies[static_cast<size_t>(s.model.bodyIndex("r_1_pelvis"))].group);
}

// Collision filtering, a given inertia and the chain's anchor size, as scene keys.
TEST(SceneFrames, FilteringInertiaAndAnchorSize) {
  const Scene s = parse(scene(R"({"name": "a", "shape": {"type": "box", "half_extents": [0.1, 0.2, 0.3]}, "mass": 2,
      "inertia": [0.1, 0.2, 0.25], "category": 4, "mask": 4, "filter_group": -3})",
                              R"("generators": [{"type": "chain", "count": 3, "anchor": [0, 5, 0], "spacing": 0.5,
      "link": {"type": "sphere", "radius": 0.1}, "anchor_radius": 0.2, "self_collision": false}])"));
  const Body& a = s.model.bodies[0];
  EXPECT_EQ(a.inertia, Vec3(0.1, 0.2, 0.25));
  EXPECT_EQ(a.invInertia, Vec3(10, 5, 4));
  EXPECT_EQ(a.mass, 2);
  EXPECT_EQ(a.category, 4u);
  EXPECT_EQ(a.mask, 4u);
  EXPECT_EQ(a.filterGroup, -3);
  const int anchor = s.model.bodyIndex("chain0_anchor"), link = s.model.bodyIndex("chain0_1");
  EXPECT_EQ(s.model.bodies[static_cast<size_t>(anchor)].shape.radius, 0.2);
  EXPECT_LT(s.model.bodies[static_cast<size_t>(link)].filterGroup, 0);
  EXPECT_FALSE(mayTouch(s.model.bodies[static_cast<size_t>(link)], s.model.bodies[static_cast<size_t>(link + 1)]));
  EXPECT_FALSE(mayTouch(s.model.bodies[static_cast<size_t>(link)], s.model.bodies[0]));  // a's mask 4 lacks category 1
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "inertia": [1, 1, 1]})"),
              "bodies[0].inertia", {"give the body's \"mass\""});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "mass": 1, "inertia": [1, 1, 3]})"),
              "bodies[0].inertia", {"at most the sum of the other two"});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "mask": 1.5})"), "bodies[0].mask",
              {"a bit mask"});
  expectError(scene(R"({"name": "a", "shape": {"type": "sphere", "radius": 1}, "category": -1})"), "bodies[0].category",
              {"in [0, 4294967295]"});
}

// ---------------------------------------------------------------- criteria (the lab's)

// A quantity a reference gives, named (as the error or a bound) without a reference that gives
// it, would measure nothing in every run: the file is refused, naming the field and what it needs.
TEST(SceneCriteria, AReferenceQuantityNeedsItsReference) {
  const std::string b = ground() + "," + kBall;
  auto with = [&](const std::string& criteria) { return scene(b, "\"criteria\": " + criteria); };
  expectError(with(R"({"error": "trajectory_error"})"), "criteria.error",
              {"trajectory_error is the distance from a reference trajectory", "the criteria state no reference",
               "give criteria.reference (pendulum, free_fall or converged"});
  expectError(with(R"({"pass": {"trajectory_error": 0.01}})"), "criteria.pass.trajectory_error", {"the criteria state no reference"});
  expectError(with(R"({"error": "trajectory_error", "reference": {"type": "torque_free"}})"), "criteria.error",
              {"a torque_free reference gives none"});
  expectError(with(R"({"error": "reference_error"})"), "criteria.error",
              {"reference_error is the error against a closed form", "give criteria.reference of type pendulum or torque_free"});
  expectError(with(R"({"pass": {"reference_error": 0.01}, "reference": {"type": "free_fall"}})"), "criteria.pass.reference_error",
              {"its error is trajectory_error"});
  // With a reference that gives them, as every scene of the repository states them.
  for (const char* ok : {R"({"error": "trajectory_error", "reference": {"type": "free_fall"}})",
                         R"({"pass": {"trajectory_error": 0.01}, "reference": {"type": "converged", "method": "a1:h=1/960"}})",
                         R"({"error": "reference_error", "reference": {"type": "pendulum", "body": "ball", "pivot": [0, 3, 0]}})",
                         R"({"error": "reference_error", "reference": {"type": "torque_free"}})"})
    EXPECT_NO_THROW(parse(with(ok))) << ok;
}

TEST(SceneCriteria, EveryPartIsRead) {
  const std::string bodies = ground() + "," + kBall + R"(, {"name": "box", "shape": {"type": "box", "half_extents": [0.5, 0.5, 0.5]}, "position": [3, 0.5, 0]})";
  const Scene s = parse(scene(bodies, R"("criteria": {
      "stresses": "a ball and a box", "seconds": 2.5, "tolerance": 0.02, "rest": ["box"], "conservative": true,
      "error": "penetration", "reference": {"type": "converged", "method": "a1:h=1/960", "change": 0.05},
      "with": {"gyroscopic": "implicit"},
      "pass": {"penetration": 0.01, "jitter": 0.05, "moving": {"bodies": "ball", "at_least": 1},
               "stay_in": {"body": "ball", "min": [-1, -1, -1], "max": [1, 3, 1]},
               "turns": {"body": "box", "axis": [0, 2, 0], "at_least": 2.5}}})"));
  ASSERT_TRUE(s.criteria);
  const SceneCriteria& c = *s.criteria;
  EXPECT_EQ(c.stresses, "a ball and a box");
  EXPECT_EQ(c.seconds, 2.5);
  EXPECT_EQ(c.tolerance, 0.02);
  EXPECT_EQ(c.rest, std::vector<int>{2});
  EXPECT_TRUE(c.conservative);
  EXPECT_EQ(c.error, "penetration");
  ASSERT_TRUE(c.reference);
  EXPECT_EQ(c.reference->kind, SceneReference::Kind::Converged);
  EXPECT_EQ(c.reference->method, "a1:h=1/960");
  EXPECT_EQ(c.reference->change, 0.05);
  EXPECT_EQ(c.with.get(&SolverSettings::gyroscopic), Gyroscopic::Implicit);
  ASSERT_EQ(c.pass.size(), 2u);
  EXPECT_EQ(c.pass[0], std::make_pair(std::string("penetration"), 0.01));
  ASSERT_TRUE(c.moving && c.stayIn && c.turns);
  EXPECT_EQ(c.moving->bodies, std::vector<int>{1});
  EXPECT_EQ(c.stayIn->hi, Vec3(1, 3, 1));
  EXPECT_EQ(c.turns->axis, Vec3::UnitY());  // normalised
  // Without the block there are no criteria; with an empty one, the defaults.
  EXPECT_FALSE(parse(scene(kBall)).criteria);
  const Scene d = parse(scene(kBall, R"("criteria": {})"));
  ASSERT_TRUE(d.criteria);
  EXPECT_EQ(d.criteria->seconds, 3);
  EXPECT_FALSE(d.criteria->tolerance);
  const Scene p = parse(scene(kBall, R"("criteria": {"reference": {"type": "pendulum", "body": "ball", "pivot": [0, 3, 0]}})"));
  EXPECT_EQ(p.criteria->reference->kind, SceneReference::Kind::Pendulum);
  EXPECT_EQ(p.criteria->reference->pivot, Vec3(0, 3, 0));
}

TEST(SceneCriteria, ErrorsNameThePath) {
  const std::string b = ground() + "," + kBall;
  auto with = [&](const std::string& criteria) { return scene(b, "\"criteria\": " + criteria); };
  expectError(with(R"({"secs": 2})"), "criteria", {"unknown key \"secs\"", "seconds"});
  expectError(with(R"({"seconds": 0})"), "criteria.seconds", {"in (0, 3600]"});
  expectError(with(R"({"tolerance": -1})"), "criteria.tolerance", {"got -1"});
  expectError(with(R"({"rest": ["ground"]})"), "criteria.rest[0]", {"\"ground\" is static"});
  expectError(with(R"({"rest": ["ball", "ball"]})"), "criteria.rest[1]", {"listed twice"});
  expectError(with(R"({"rest": []})"), "criteria.rest", {"non-empty array"});
  expectError(with(R"({"error": "wobble"})"), "criteria.error", {"unknown quantity \"wobble\"", "joint_error"});
  expectError(with(R"({"pass": {"penetration": -0.1}})"), "criteria.pass.penetration", {"in [0, 1e9]"});
  expectError(with(R"({"pass": {"wobble": 1}})"), "criteria.pass", {"unknown key \"wobble\""});
  expectError(with(R"({"pass": {"moving": {"bodies": ["nobody"], "at_least": 1}}})"), "criteria.pass.moving.bodies[0]",
              {"unknown body \"nobody\""});
  expectError(with(R"({"pass": {"stay_in": {"body": "ball", "min": [0, 0, 0], "max": [1, 1, 1]}}})"),
              "criteria.pass.stay_in", {"starts outside the box (axis y)"});
  expectError(with(R"({"pass": {"stay_in": {"body": "ball", "min": [0, 0, 0], "max": [0, 3, 1]}}})"),
              "criteria.pass.stay_in", {"expected min < max", "axis x"});
  expectError(with(R"({"pass": {"turns": {"body": "ball", "axis": [0, 0, 0], "at_least": 1}}})"),
              "criteria.pass.turns.axis", {"non-zero vector"});
  expectError(with(R"({"reference": {"type": "analytic"}})"), "criteria.reference.type", {"unknown reference type"});
  expectError(with(R"({"reference": {"type": "pendulum", "body": "ball", "pivot": [0, 2, 0]}})"), "criteria.reference.pivot",
              {"at the body's centre"});
  expectError(with(R"({"reference": {"type": "converged", "method": "a1"}})"), "criteria.reference.method",
              {"give the reference's time step"});
  expectError(with(R"({"reference": {"type": "converged", "method": "a1:h=1/960|1/480"}})"), "criteria.reference.method",
              {"a grid of 2"});
  expectError(with(R"({"reference": {"type": "converged", "method": "bullet:h=0.001"}})"), "criteria.reference.method",
              {"not the bullet peer"});
  expectError(with(R"({"reference": {"type": "converged", "method": "a1:h=0.001", "change": 0}})"),
              "criteria.reference.change", {"in (0, 1]"});
  expectError(with(R"({"with": {"algorithm": "a5"}})"), "criteria.with", {"the algorithm and presets are the method's"});
  expectError(with(R"({"with": {"kappa": 0}})"), "criteria.with.kappa", {"in (0, 10]"});
}
