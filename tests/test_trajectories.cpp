// Bit-identical trajectories: every scene of assets/scenes under every algorithm (and a few
// extensions on the small scenes), stepped for a second, against a table of state hashes
// (tests/data/trajectory_hashes.json). A change that moves any body of any of these runs by one
// bit fails here; a change meant to move them rewrites the table on purpose:
//     SUBSTEP_UPDATE_HASHES=1 build/tests/test_trajectories
// The table holds one toolchain's numbers (the compiler and flags change the last bits): other
// builds skip, saying so.
#include "physics/scene_file.h"
#include "physics/settings.h"
#include "physics/state_hash.h"
#include "physics/world.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>

using namespace substep;
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

const std::string kTable = std::string(SUBSTEP_SOURCE_DIR) + "/tests/data/trajectory_hashes.json";
constexpr int kSteps = 60;

std::string toolchain() {
  std::string t = std::string("gcc/clang ") + __VERSION__;
#ifdef NDEBUG
  t += ", NDEBUG";
#endif
#ifdef __OPTIMIZE__
  t += ", optimised";
#endif
#ifdef __FMA__
  t += ", FMA";
#endif
  return t;
}

// Scenes by their path under assets/scenes, without .json.
std::vector<std::string> sceneNames() {
  std::vector<std::string> names;
  const fs::path root = fs::path(SUBSTEP_SOURCE_DIR) / "assets/scenes";
  // bench/pile_10000 is pile.json ten times over: its six runs would add a third to this test's
  // time.
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.path().extension() == ".json" && e.path().stem() != "pile_10000")
      names.push_back(fs::relative(e.path(), root).replace_extension().string());
  std::sort(names.begin(), names.end());
  return names;
}

// The methods every scene runs under (as `substep run SCENE --algo X`: the scene's solver block
// under the method), and the extensions the small scenes run under too.
const std::vector<std::string> kAlgorithmNames = {"a1", "a2", "a3", "a4", "a5", "soft"};
const std::vector<std::string> kSmallScenes = {"stack", "chain", "pyramid", "ragdoll_pile", "shapes", "mass_ratio"};
const std::vector<std::string> kExtensions = {
    "a2:warm=on:split=on", "a2:omega=1.3:tol=0", "a3:warm=on",          "a4:cblock=on",
    "a5:jacobians=stable", "a5:islands=off",     "a5:warm=on:cblock=on:kappa=0.85:tau=0",
    "a5:gyro=implicit",    "soft:n=8:contact_hertz=60", "soft:colours=on"};

// What one run ended with.
json runOnce(const Scene& scene, const std::string& method) {
  const MethodSpec m = expandMethodSpec(method).at(0);
  const SolverSettings s = resolveFor(scene.solver, m.overrides);
  World world(scene.model, s, scene.initial);
  json r;
  try {
    for (int k = 0; k < kSteps; ++k) {
      const StepReport& rep = world.step();
      if (k == 0) r["first"] = hashText(stateHash(world.state()));
      if (!rep.finite) {
        r["stopped"] = k + 1;
        break;
      }
    }
  } catch (const Refused&) {  // A1 beyond its size: refused at its first step
    r["refused"] = true;
  }
  r["steps"] = world.state().step;
  r["hash"] = hashText(stateHash(world.state()));
  return r;
}

}  // namespace

TEST(Trajectories, BitIdenticalToTheTable) {
  json table;
  {
    std::ifstream in(kTable);
    if (in) table = json::parse(in);
  }
  const bool update = std::getenv("SUBSTEP_UPDATE_HASHES") != nullptr;
  if (!update) {
    ASSERT_TRUE(table.is_object()) << kTable << " is missing; write it with SUBSTEP_UPDATE_HASHES=1";
    if (table.value("toolchain", "") != toolchain())
      GTEST_SKIP() << "the table holds the hashes of " << table.value("toolchain", "?") << "; this build is "
                   << toolchain();
  }
  json runs = json::object();
  int differ = 0, compared = 0;
  for (const std::string& name : sceneNames()) {
    const Scene scene = loadScene(std::string(SUBSTEP_SOURCE_DIR) + "/assets/scenes/" + name + ".json");
    std::vector<std::string> methods = kAlgorithmNames;
    if (std::find(kSmallScenes.begin(), kSmallScenes.end(), name) != kSmallScenes.end())
      methods.insert(methods.end(), kExtensions.begin(), kExtensions.end());
    for (const std::string& method : methods) {
      const std::string key = name + " | " + method;
      const json got = runOnce(scene, method);
      runs[key] = got;
      if (update) continue;
      ++compared;
      const auto want = table["runs"].find(key);
      if (want == table["runs"].end()) {
        ADD_FAILURE() << key << ": not in the table (rewrite it with SUBSTEP_UPDATE_HASHES=1)";
        ++differ;
      } else if (*want != got) {
        ADD_FAILURE() << key << ": " << got.dump() << ", the table has " << want->dump();
        ++differ;
      }
    }
  }
  if (update) {
    const json out = {{"toolchain", toolchain()}, {"steps", kSteps}, {"runs", runs}};
    std::ofstream(kTable) << out.dump(1) << "\n";
    std::printf("wrote %s: %zu runs\n", kTable.c_str(), runs.size());
    return;
  }
  std::printf("%d of %d runs bit-identical to the table\n", compared - differ, compared);
  EXPECT_EQ(table["runs"].size(), runs.size()) << "the table has runs this test no longer makes";
}
