// substep rerun: a record runs again to the same bits (exit 0), a record changed in one setting
// names the first step and the bodies that differ (1), and a record that lacks what a re-run
// needs, or whose scene is gone or changed, is bad input (2). Records of `run --metrics`, of a
// sweep's JSONL (substep's algorithms and the Bullet peer) alike.
#include "run_substep.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

using namespace substep_test;
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

fs::path scratch() { return emptyScratchFolder("test_rerun_out"); }

json readJson(const fs::path& p) {
  std::ifstream in(p);
  return json::parse(in);
}

void writeJson(const fs::path& p, const json& j) { std::ofstream(p) << j.dump() << "\n"; }

std::vector<json> readLines(const fs::path& p) {
  std::ifstream in(p);
  std::vector<json> out;
  for (std::string l; std::getline(in, l);)
    if (!l.empty()) out.push_back(json::parse(l));
  return out;
}

void writeLines(const fs::path& p, const std::vector<json>& rows) {
  std::ofstream out(p);
  for (const json& r : rows) out << r.dump() << "\n";
}

}  // namespace

// The acceptance lines of issue 21: run, re-run: 0; one setting edited in the record: 1, naming
// the first difference.
TEST(Rerun, RunMetricsAreTheSameAndAnEditedSettingNamesTheFirstDifference) {
  const fs::path d = scratch(), m = d / "m.json";
  Outcome r = runSubstep("run assets/scenes/stack.json --algo a5 --metrics " + m.string() + " -q");
  ASSERT_EQ(r.status, 0) << r.output;
  const json rec = readJson(m);
  for (const char* k : {"scene_file", "scene_hash", "settings", "commit", "threads", "state_hash", "state_hashes"})
    EXPECT_TRUE(rec.contains(k)) << k;
  EXPECT_EQ(rec["settings"]["algorithm"], "a5");
  EXPECT_EQ(rec["settings"]["speculative"], true);  // every resolved setting, extensions too
  r = runSubstep("rerun " + m.string());
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("the same, bit for bit (state hash " + rec["state_hash"].get<std::string>() + " at step 300)"),
            std::string::npos)
      << r.output;

  json edited = rec;
  edited["settings"]["kappa"] = 0.9;
  writeJson(d / "kappa.json", edited);
  r = runSubstep("rerun " + (d / "kappa.json").string());
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("DIFFERS"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("κ=0.9"), std::string::npos) << r.output;  // it ran what the record now says
  EXPECT_NE(r.output.find("first differs at step 1 (t = 0.017 s): bodies stack_0, stack_1"), std::string::npos) << r.output;

  // A difference that starts later is named at its step: here the record's own hash of step 100
  // is made wrong, so that the re-run leaves it there.
  json late = rec;
  for (json& p : late["state_hashes"]["steps"])
    if (p[0] == 100) p[1] = "0123456789abcdef";
  writeJson(d / "late.json", late);
  r = runSubstep("rerun " + (d / "late.json").string());
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("first differs at step 100 (t = 1.667 s)"), std::string::npos) << r.output;
}

TEST(Rerun, IncompleteRecordsAndGoneOrChangedScenesAreBadInput) {
  const fs::path d = scratch(), m = d / "m.json", scene = d / "stack.json";
  fs::copy_file(fs::path(SUBSTEP_SOURCE_DIR) / "assets/scenes/stack.json", scene);
  Outcome r = runSubstep("run " + scene.string() + " --steps 30 --metrics " + m.string() + " -q");
  ASSERT_EQ(r.status, 0) << r.output;
  const json rec = readJson(m);
  for (const char* field : {"state_hash", "state_hashes", "scene_hash", "settings", "steps_done"}) {
    json cut = rec;
    cut.erase(field);
    writeJson(d / "cut.json", cut);
    r = runSubstep("rerun " + (d / "cut.json").string());
    EXPECT_EQ(r.status, 2) << field << "\n" << r.output;
    EXPECT_NE(r.output.find("the record has no \"" + std::string(field) + "\""), std::string::npos) << r.output;
  }
  json noKey = rec;
  noKey["settings"].erase("islands");
  writeJson(d / "cut.json", noKey);
  r = runSubstep("rerun " + (d / "cut.json").string());
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("settings: no islands"), std::string::npos) << r.output;

  {  // the scene changed: one space more is another content
    std::ofstream(scene, std::ios::app) << " ";
  }
  r = runSubstep("rerun " + m.string());
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("changed since the record was made"), std::string::npos) << r.output;
  fs::remove(scene);
  r = runSubstep("rerun " + m.string());
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("is gone"), std::string::npos) << r.output;
  r = runSubstep("rerun " + (d / "none.json").string());
  EXPECT_EQ(r.status, 2) << r.output;
}

// A sweep's records, substep's and the Bullet peer's, each re-run; one edited line differs alone.
TEST(Rerun, SweepLinesOneByOneOrAll) {
  const fs::path d = scratch(), out = d / "s.jsonl";
  Outcome r = runSubstep("sweep --scenes stack --methods 'a2:m=4,a5:n=2,bullet:it=10' --seconds 0.5 -q -o " + out.string());
  ASSERT_EQ(r.status, 0) << r.output;
  r = runSubstep("rerun " + out.string());
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("3 of 3 records the same"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("under bullet it=10"), std::string::npos) << r.output;
  std::vector<json> rows = readLines(out);
  ASSERT_EQ(rows.size(), 3u);
  r = runSubstep("rerun " + out.string() + " --key '" + rows[1]["key"].get<std::string>() + "'");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("a5 n=2"), std::string::npos) << r.output;
  rows[1]["settings"]["substeps"] = 3;
  writeLines(d / "edited.jsonl", rows);
  r = runSubstep("rerun " + (d / "edited.jsonl").string());
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("line 2"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("2 of 3 records the same, 1 differ"), std::string::npos) << r.output;
  r = runSubstep("rerun " + (d / "edited.jsonl").string() + " --line 3");
  EXPECT_EQ(r.status, 0) << r.output;
  r = runSubstep("rerun " + (d / "edited.jsonl").string() + " --line 9");
  EXPECT_EQ(r.status, 2) << r.output;
}

// A run its algorithm refused is re-run to the same refusal.
TEST(Rerun, ARefusedRunIsRefusedAgain) {
  const fs::path d = scratch(), out = d / "a1.jsonl";
  Outcome r = runSubstep("sweep --scenes pyramid --methods a1 --seconds 0.1 -q -o " + out.string());
  ASSERT_EQ(r.status, 0) << r.output;
  r = runSubstep("rerun " + out.string());
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("refused again at step 1, as the record (a1 solves the MLCP"), std::string::npos) << r.output;
}
