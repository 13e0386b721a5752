// The failure atlas's verdicts, held (docs/lab.md, "The failure atlas"): every atlas scene under
// the default methods, each cell's pass / fail / refused against tests/data/atlas_expected.json.
// A change that turns a pass into a fail, or a fail into a pass, fails here until the table is
// rewritten on purpose:
//   build/app/substep atlas --no-clips -o out/atlas --write-expected tests/data/atlas_expected.json
// The verdicts come from the physics runs alone (no clips, no charts), each run stopped once a
// bound is missed for good (the verdict cannot change after); one test per scene, so CTest spreads
// them over the cores.
#include "lab/atlas.h"
#include "lab/record.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <set>

using namespace substep;
using namespace substep::lab;

namespace {

const std::string kAtlas = SUBSTEP_SOURCE_DIR "/assets/scenes/atlas";
const std::string kExpected = SUBSTEP_SOURCE_DIR "/tests/data/atlas_expected.json";

std::vector<std::string> sceneNames() {
  std::vector<std::string> names;
  for (const std::string& f : atlasScenes(kAtlas)) names.push_back(std::filesystem::path(f).stem().string());
  return names;
}

class Atlas : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(Atlas, VerdictsAreTheExpectedOnes) {
  const VerdictTable expected = readVerdicts(kExpected);
  const Scene scene = loadScene(kAtlas + "/" + GetParam() + ".json");
  ASSERT_TRUE(scene.criteria) << "an atlas scene states its pass criteria";
  ASSERT_EQ(expected.count(GetParam()), 1u) << GetParam() << " has no row in " << kExpected;
  const auto& row = expected.at(GetParam());
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<AtlasCell> cells =
      runAtlasScene(scene, parseMethods(defaultAtlasMethods()), 0, 1, "", /*verdictsOnly=*/true);
  for (const AtlasCell& c : cells) {
    const std::string got = resultName(c.verdict.result);
    std::printf("%-22s %-20s %-8s %s\n", GetParam().c_str(), c.run.method.text.c_str(), got.c_str(), c.verdict.figure.c_str());
    const auto want = row.find(c.run.method.text);
    ASSERT_NE(want, row.end()) << GetParam() << ": no expected verdict for " << c.run.method.text;
    EXPECT_EQ(got, want->second) << GetParam() << " under " << c.run.method.text << " now reads \"" << c.verdict.figure
                                 << "\". If the change is meant, rewrite the table:\n  build/app/substep atlas --no-clips "
                                    "-o out/atlas --write-expected tests/data/atlas_expected.json";
  }
  std::printf("%s: %.1f s\n", GetParam().c_str(),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}

INSTANTIATE_TEST_SUITE_P(Scenes, Atlas, ::testing::ValuesIn(sceneNames()),
                         [](const ::testing::TestParamInfo<std::string>& i) { return i.param; });

// The table and the atlas agree on what there is: a scene added to the atlas needs its row, a
// method added to the default set its column.
TEST(AtlasTable, CoversEveryAtlasSceneAndEveryDefaultMethod) {
  const VerdictTable expected = readVerdicts(kExpected);
  std::set<std::string> scenes, rows;
  for (const std::string& n : sceneNames()) scenes.insert(n);
  for (const auto& [scene, row] : expected) {
    rows.insert(scene);
    std::set<std::string> methods, want;
    for (const auto& [m, v] : row) {
      methods.insert(m);
      EXPECT_TRUE(v == "pass" || v == "fail" || v == "refused") << scene << " " << m << ": " << v;
    }
    for (const Method& m : parseMethods(defaultAtlasMethods())) want.insert(m.text);
    EXPECT_EQ(methods, want) << scene;
  }
  EXPECT_EQ(rows, scenes);
}
