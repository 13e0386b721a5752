// Recordings (physics/recording.h, docs/recordings.md): a recorded run reads back bit for bit,
// `--every` thins it, a damaged file is refused with its reason and never crashes, the writer
// leaves no temporary behind, and run / sweep / atlas --record write what they say.
#include "lab/record.h"
#include "physics/recording.h"
#include "physics/scene_file.h"
#include "physics/settings.h"
#include "physics/settings_json.h"
#include "physics/world.h"
#include "run_substep.h"

#include <gtest/gtest.h>
#include <xxhash.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace {

using namespace substep;
using substep_test::runSubstep;
namespace fs = std::filesystem;
using json = nlohmann::json;

Scene scene(const std::string& name) { return loadScene(SUBSTEP_SOURCE_DIR "/assets/scenes/" + name + ".json"); }

// What the World had after each step, collected by the test itself.
class Collect final : public RunObserver {
 public:
  void begin(const Engine& e) override { take(e); }
  void observe(const Engine& e, const StepRecord& r) override {
    if (r.finite) take(e);
  }
  std::vector<Snapshot> frames;

 private:
  void take(const Engine& e) { frames.push_back(takeSnapshot(*e.world())); }
};

struct Recorded {
  Recording rec;
  std::vector<Snapshot> truth;
};

Recorded recordRun(const Scene& sc, long long steps, long long every, const fs::path& file, const SolverOverrides& extra = {}) {
  const SolverSettings settings = resolve(sc.solver.merged(extra));
  World world(sc.model, settings, sc.initial);
  WorldEngine engine(world);
  RunDriver run(engine, steps);
  Collect collect;
  Recorded out;
  {
    RecordingWriter w(file.string(), lab::recordingMeta(sc, {{"", settingsJson(settings), "", "substep"}}, every, steps));
    RecordingObserver rec(w, sc.model, 0, every, steps);
    run.add(collect).add(rec);
    EXPECT_EQ(run.run().end, RunOutcome::End::Planned);
    w.commit();
  }
  out.truth = std::move(collect.frames);
  out.rec = readRecording(file.string());
  return out;
}

bool sameBits(const BodyState& a, const BodyState& b) {
  const double x[13] = {a.x.x(), a.x.y(), a.x.z(), a.q.w(), a.q.x(), a.q.y(), a.q.z(), a.v.x(), a.v.y(), a.v.z(), a.w.x(), a.w.y(), a.w.z()};
  const double y[13] = {b.x.x(), b.x.y(), b.x.z(), b.q.w(), b.q.x(), b.q.y(), b.q.z(), b.v.x(), b.v.y(), b.v.z(), b.w.x(), b.w.y(), b.w.z()};
  return std::memcmp(x, y, sizeof x) == 0;
}

template <class T>
bool sameFloats(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

void expectSameFrames(const Snapshot& got, const Snapshot& want, size_t k) {
  ASSERT_EQ(got.state.step, want.state.step) << "frame " << k;
  EXPECT_EQ(std::memcmp(&got.state.time, &want.state.time, sizeof(double)), 0) << "frame " << k;
  ASSERT_EQ(got.state.bodies.size(), want.state.bodies.size());
  for (size_t i = 0; i < want.state.bodies.size(); ++i)
    ASSERT_TRUE(sameBits(got.state.bodies[i], want.state.bodies[i])) << "frame " << k << ", body " << i;
  ASSERT_EQ(got.manifolds.size(), want.manifolds.size()) << "frame " << k;
  for (size_t i = 0; i < want.manifolds.size(); ++i) {
    const ManifoldSnap &a = got.manifolds[i], &b = want.manifolds[i];
    EXPECT_TRUE(a.a == b.a && a.b == b.b && a.first == b.first && a.count == b.count && a.friction == b.friction && a.twist == b.twist)
        << "frame " << k << ", manifold " << i;
  }
  ASSERT_EQ(got.contacts.size(), want.contacts.size()) << "frame " << k;
  for (size_t i = 0; i < want.contacts.size(); ++i) {
    const ContactSnap &a = got.contacts[i], &b = want.contacts[i];
    EXPECT_TRUE(a.point == b.point && a.normal == b.normal && a.depth == b.depth && a.normalImpulse == b.normalImpulse)
        << "frame " << k << ", contact " << i;
  }
  ASSERT_EQ(got.joints.size(), want.joints.size()) << "frame " << k;
  for (size_t i = 0; i < want.joints.size(); ++i) {
    const JointSnap &a = got.joints[i], &b = want.joints[i];
    EXPECT_TRUE(a.error == b.error && a.linear == b.linear && a.angular == b.angular) << "frame " << k << ", joint " << i;
  }
  EXPECT_EQ(got.asleep, want.asleep) << "frame " << k;
}

fs::path scratch() { return substep_test::emptyScratchFolder("recording"); }

std::string readBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The problem parseRecording reports for `bytes`, and its message.
std::pair<RecordingError::Problem, std::string> refusal(const std::string& bytes) {
  try {
    parseRecording(bytes, "x.rec");
  } catch (const RecordingError& e) {
    return {e.problem(), e.what()};
  }
  ADD_FAILURE() << "parsed without complaint";
  return {RecordingError::Problem::Unreadable, ""};
}

// Recomputes the footer's checksum, so that a change made on purpose is seen by the structure
// checks instead of the checksum (a writer with a bug, not a flipped bit).
std::string reseal(std::string b) {
  const size_t at = b.size() - 27;
  uint64_t h = XXH3_64bits(b.data(), at + 9);
  for (int i = 0; i < 8; ++i) b[at + 9 + static_cast<size_t>(i)] = static_cast<char>((h >> (8 * i)) & 0xff);
  return b;
}
void putU32(std::string& b, size_t at, uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + static_cast<size_t>(i)] = static_cast<char>((v >> (8 * i)) & 0xff);
}

// A small recording of the stack, and where its first frame starts.
struct Small {
  std::string bytes;
  size_t firstFrame;
};
Small smallRecording(const fs::path& dir) {
  const Scene sc = scene("stack");
  recordRun(sc, 12, 1, dir / "small.rec");
  Small s{readBytes(dir / "small.rec"), 0};
  uint32_t n = 0;
  for (int i = 0; i < 4; ++i) n |= static_cast<uint32_t>(static_cast<unsigned char>(s.bytes[14 + static_cast<size_t>(i)])) << (8 * i);
  s.firstFrame = 18 + n;
  return s;
}

TEST(Recording, StackingRunReadsBackBitForBit) {
  const fs::path dir = scratch();
  const Scene sc = scene("pyramid");
  const Recorded r = recordRun(sc, 90, 1, dir / "pyramid.rec");
  ASSERT_EQ(r.rec.panels.size(), 1u);
  ASSERT_EQ(r.rec.panels[0].size(), r.truth.size());
  size_t contacts = 0;
  for (size_t k = 0; k < r.truth.size(); ++k) {
    expectSameFrames(r.rec.panels[0][k], r.truth[k], k);
    contacts += r.truth[k].contacts.size();
  }
  EXPECT_GT(contacts, 0u);  // the comparison covered contacts
  EXPECT_EQ(r.rec.meta["format"], "substep-recording");
  EXPECT_EQ(r.rec.meta["planned_steps"], 90);
  EXPECT_TRUE(r.rec.meta.contains("commit"));
  // The scene it carries is the one that ran.
  const Scene back = recordingScene(r.rec);
  EXPECT_EQ(back.hash, sc.hash);
  EXPECT_EQ(back.model.bodies.size(), sc.model.bodies.size());
}

TEST(Recording, RagdollRunReadsBackBitForBit) {
  const fs::path dir = scratch();
  const Scene sc = scene("ragdoll");
  ASSERT_FALSE(sc.model.joints.empty());
  const Recorded r = recordRun(sc, 60, 1, dir / "ragdoll.rec");
  ASSERT_EQ(r.rec.panels[0].size(), r.truth.size());
  for (size_t k = 0; k < r.truth.size(); ++k) expectSameFrames(r.rec.panels[0][k], r.truth[k], k);
  float impulse = 0;
  for (const JointSnap& j : r.truth.back().joints) impulse += j.linear.norm();
  EXPECT_GT(impulse, 0.f);  // joint impulses were compared, not zeros
}

// Version 2 frames end with the bodies asleep after the step: a run with sleeping keeps them, and a
// version 1 file (the same frames without that list) still reads, with none asleep.
TEST(Recording, SleepingBodiesAreKeptAndVersionOneStillReads) {
  const fs::path dir = scratch();
  SolverOverrides sleep;
  sleep.set(&SolverSettings::sleep, true);
  const Recorded r = recordRun(scene("stack"), 150, 1, dir / "sleep.rec", sleep);
  ASSERT_EQ(r.rec.panels[0].size(), r.truth.size());
  for (size_t k = 0; k < r.truth.size(); ++k) expectSameFrames(r.rec.panels[0][k], r.truth[k], k);
  ASSERT_EQ(r.truth.back().asleep.size(), 5u) << "the stack's five boxes sleep by 2.5 s";
  EXPECT_TRUE(r.truth.front().asleep.empty());

  // The same recording written as version 1: without the asleep lists.
  const Recorded awake = recordRun(scene("stack"), 12, 1, dir / "awake.rec");
  std::string b = readBytes(dir / "awake.rec"), v1 = b.substr(0, 10);
  v1 += std::string("\x01\0\0\0", 4);
  uint32_t metaBytes = 0;
  for (int i = 0; i < 4; ++i) metaBytes |= static_cast<uint32_t>(static_cast<unsigned char>(b[14 + static_cast<size_t>(i)])) << (8 * i);
  size_t at = 14;
  v1 += b.substr(at, 4 + metaBytes);
  at += 4 + metaBytes;
  auto u32at = [&](size_t p) {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= static_cast<uint32_t>(static_cast<unsigned char>(b[p + static_cast<size_t>(i)])) << (8 * i);
    return v;
  };
  while (b[at] == 'F') {
    size_t end = at + 1 + 4 + 8 + 8;
    end += 4 + 104 * size_t(u32at(end));
    end += 4 + 32 * size_t(u32at(end));
    end += 4 + 32 * size_t(u32at(end));
    end += 4 + 28 * size_t(u32at(end));
    ASSERT_EQ(u32at(end), 0u);  // nothing asleep: the list is its count alone
    v1 += b.substr(at, end - at);
    at = end + 4;
  }
  v1 += b.substr(at);
  const Recording old = parseRecording(reseal(v1), "old.rec");
  ASSERT_EQ(old.panels[0].size(), awake.truth.size());
  for (size_t k = 0; k < awake.truth.size(); ++k) expectSameFrames(old.panels[0][k], awake.truth[k], k);
}

TEST(Recording, EveryKeepsEveryKthStepAndTheLast) {
  const fs::path dir = scratch();
  const Recorded r = recordRun(scene("stack"), 23, 5, dir / "every.rec");
  std::vector<long long> steps;
  for (const Snapshot& s : r.rec.panels[0]) steps.push_back(s.state.step);
  EXPECT_EQ(steps, (std::vector<long long>{0, 5, 10, 15, 20, 23}));
  for (const Snapshot& s : r.rec.panels[0]) expectSameFrames(s, r.truth[static_cast<size_t>(s.state.step)], 0);
}

TEST(Recording, TruncatedAnywhereIsRefusedAsTruncated) {
  const Small s = smallRecording(scratch());
  const size_t n = s.bytes.size();
  std::vector<size_t> cuts;
  for (size_t k = 1; k < s.firstFrame + 300; k += (k < 40 ? 1 : 7)) cuts.push_back(k);      // header, metadata, frame 0
  for (size_t k = s.firstFrame; k < n; k += 331) cuts.push_back(k);                           // throughout
  for (size_t k = n - 30; k < n; ++k) cuts.push_back(k);                                     // the last frame, the footer
  for (size_t k : cuts) {
    const auto [p, msg] = refusal(s.bytes.substr(0, k));
    ASSERT_EQ(p, RecordingError::Problem::Truncated) << "cut at " << k << ": " << msg;
    EXPECT_NE(msg.find("x.rec: truncated at byte " + std::to_string(k)), std::string::npos) << msg;
  }
  EXPECT_NE(refusal(s.bytes.substr(0, s.firstFrame + 50)).second.find("(in frame 0"), std::string::npos);
  EXPECT_NE(refusal(s.bytes.substr(0, n - 27)).second.find("the footer is missing"), std::string::npos);
  EXPECT_EQ(refusal("").first, RecordingError::Problem::NotRecording);
}

TEST(Recording, AFlippedByteAnywhereIsRefused) {
  const Small s = smallRecording(scratch());
  for (size_t k = 0; k < s.bytes.size(); k += (k < 64 ? 1 : 13)) {
    for (unsigned char bit : {0x01, 0x80}) {
      std::string b = s.bytes;
      b[k] = static_cast<char>(b[k] ^ bit);
      const auto [p, msg] = refusal(b);
      if (k < 10)
        ASSERT_EQ(p, RecordingError::Problem::NotRecording) << k << ": " << msg;
      else if (k < 14)
        ASSERT_EQ(p, RecordingError::Problem::Version) << k << ": " << msg;
      else
        ASSERT_EQ(p, RecordingError::Problem::Corrupt) << k << ": " << msg;
    }
  }
  std::string b = s.bytes;
  b[s.firstFrame + 40] ^= 0x10;
  EXPECT_NE(refusal(b).second.find("x.rec: checksum mismatch"), std::string::npos);
}

TEST(Recording, WrongMagicAndUnknownVersionAreNamed) {
  const Small s = smallRecording(scratch());
  std::string b = s.bytes;
  b.replace(0, 10, "{\"scenes\":");
  EXPECT_EQ(refusal(b).second, "x.rec: not a recording (it does not start with SUBSTEPREC)");
  b = s.bytes;
  putU32(b, 10, 99);
  const auto [p, msg] = refusal(b);
  EXPECT_EQ(p, RecordingError::Problem::Version);
  EXPECT_EQ(msg, "x.rec: unknown version 99 (this build reads versions 1 to 2)");
  b = s.bytes + "junk";
  EXPECT_NE(refusal(b).second.find("4 bytes after the end"), std::string::npos);
}

TEST(Recording, AbsurdCountsAreRefusedAsTooLarge) {
  const Small s = smallRecording(scratch());
  const size_t bodiesAt = s.firstFrame + 21;
  std::string b = s.bytes;
  putU32(b, bodiesAt, 0xffffffffu);
  auto r = refusal(reseal(b));
  EXPECT_EQ(r.first, RecordingError::Problem::TooLarge) << r.second;
  EXPECT_NE(r.second.find("4294967295 bodies; the metadata says"), std::string::npos) << r.second;
  // Manifolds: right after the bodies.
  const uint32_t bodies = static_cast<uint32_t>(scene("stack").model.bodies.size());
  b = s.bytes;
  putU32(b, bodiesAt + 4 + 104 * bodies, 0x7fffffffu);
  r = refusal(reseal(b));
  EXPECT_EQ(r.first, RecordingError::Problem::TooLarge) << r.second;
  EXPECT_NE(r.second.find("beyond the file"), std::string::npos) << r.second;
  // The metadata's length beyond the file.
  b = s.bytes;
  putU32(b, 14, 0xfffffff0u);
  r = refusal(reseal(b));
  EXPECT_EQ(r.first, RecordingError::Problem::TooLarge) << r.second;
  // A file beyond the reader's limit is not read.
  const fs::path dir = scratch();
  std::ofstream(dir / "big.rec", std::ios::binary) << s.bytes;
  try {
    readRecording((dir / "big.rec").string(), 1000);
    ADD_FAILURE() << "read";
  } catch (const RecordingError& e) {
    EXPECT_EQ(e.problem(), RecordingError::Problem::TooLarge);
    EXPECT_NE(std::string(e.what()).find((dir / "big.rec").string() + ": too large: "), std::string::npos) << e.what();
  }
}

TEST(Recording, WriterLeavesNoTemporary) {
  const fs::path dir = scratch();
  const Scene sc = scene("stack");
  const json meta = lab::recordingMeta(sc, {{"", json::object(), "", "substep"}}, 1, 1);
  {
    RecordingWriter w((dir / "a.rec").string(), meta);
    w.add(0, takeSnapshot(sc.model, sc.initial));
    EXPECT_TRUE(fs::exists(w.tempPath()));
    EXPECT_FALSE(fs::exists(dir / "a.rec"));
    w.commit();
  }
  {
    RecordingWriter w((dir / "b.rec").string(), meta);
    w.add(0, takeSnapshot(sc.model, sc.initial));
  }  // never committed: an error or Ctrl-C
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  EXPECT_EQ(names, std::vector<std::string>{"a.rec"});
  EXPECT_EQ(readRecording((dir / "a.rec").string()).frames(), 1);
  EXPECT_THROW(RecordingWriter((dir / "none" / "c.rec").string(), meta), RecordingError);
}

// --- the commands ---------------------------------------------------------------------------------

TEST(RecordingCli, RunRecordWritesTheKeptSteps) {
  const fs::path dir = scratch();
  const auto r = runSubstep("run assets/scenes/ragdoll.json --steps 20 --every 5 --record " + (dir / "r.rec").string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("wrote     " + (dir / "r.rec").string() + " (5 frames, "), std::string::npos) << r.output;
  const Recording rec = readRecording((dir / "r.rec").string());
  ASSERT_EQ(rec.panels[0].size(), 5u);
  EXPECT_EQ(rec.panels[0].back().state.step, 20);
  EXPECT_EQ(rec.meta["every"], 5);
  EXPECT_EQ(rec.meta["panels"][0]["settings"]["algorithm"], rec.meta["settings"]["algorithm"]);
}

TEST(RecordingCli, RunRecordRefusesBadOutputsBeforeStepping) {
  const fs::path dir = scratch();
  auto r = runSubstep("run assets/scenes/stack.json --steps 100000 --record /proc/forbidden/r.rec");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("--record /proc/forbidden/r.rec"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("stepped"), std::string::npos) << r.output;
  r = runSubstep("run assets/scenes/stack.json --steps 1 --record ''");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("--record: expected a file name"), std::string::npos) << r.output;
  r = runSubstep("run assets/scenes/stack.json --steps 1 --trajectory " + (dir / "x").string() + " --record " +
                 (dir / "." / "x").string());
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("--trajectory and --record name the same file"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::is_empty(dir));
}

TEST(RecordingCli, SweepRecordsEveryRunAndNamesIt) {
  const fs::path dir = scratch();
  const auto r = runSubstep("sweep --scenes box_on_ground --methods a2:m=4,a5 --dt 1/60,1/120 --seconds 0.1 -q -o " +
                            (dir / "s.jsonl").string() + " --record " + (dir / "recs").string());
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream in(dir / "s.jsonl");
  std::string line;
  std::vector<std::string> names;
  while (std::getline(in, line)) {
    const json row = json::parse(line);
    ASSERT_TRUE(row["recording"].is_string()) << line;
    names.push_back(row["recording"].get<std::string>());
    const Recording rec = readRecording((dir / names.back()).string());
    EXPECT_EQ(rec.panels[0].back().state.step, row["steps_done"].get<long long>());
    EXPECT_EQ(rec.meta["panels"][0]["method"], row["method"]);
  }
  EXPECT_EQ(names, (std::vector<std::string>{"recs/box_on_ground-a2_m=4-h1_60.rec", "recs/box_on_ground-a2_m=4-h1_120.rec",
                                             "recs/box_on_ground-a5-h1_60.rec", "recs/box_on_ground-a5-h1_120.rec"}));
}

TEST(RecordingCli, AtlasRecordsEveryCell) {
  const fs::path dir = scratch();
  const auto r = runSubstep("atlas --no-clips --scenes projectile_wall --methods a2:m=4,bullet:it=10 -q -o " + dir.string() +
                            " --record " + (dir / "recs").string());
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream in(dir / "atlas.json");
  const json atlas = json::parse(in);
  const json& cells = atlas["scenes"][0]["cells"];
  ASSERT_EQ(cells.size(), 2u);
  EXPECT_EQ(cells[0]["recording"], "recs/projectile_wall-a2_m=4.rec");
  EXPECT_EQ(cells[1]["recording"], "recs/projectile_wall-bullet_it=10.rec");
  const Recording bullet = readRecording((dir / cells[1]["recording"].get<std::string>()).string());
  EXPECT_EQ(bullet.meta["panels"][0]["engine"], "bullet");
  EXPECT_GT(bullet.frames(), 1);
  std::ifstream rows(dir / "atlas.jsonl");
  std::string line;
  std::getline(rows, line);
  EXPECT_EQ(json::parse(line)["recording"], "recs/projectile_wall-a2_m=4.rec");
}

}  // namespace

// `substep render x.rec` draws the recording without stepping: its frame at t is the frame the run
// itself draws at t (same pixels), a video covers the recording, and a damaged recording exits 2
// saying what is wrong, writing nothing.
TEST(RecordingCli, RenderDrawsARecordingAsTheRunDrawsIt) {
  const fs::path dir = scratch();
  const std::string rec = (dir / "r.rec").string();
  ASSERT_EQ(runSubstep("run assets/scenes/ragdoll.json --seconds 1 -q --record " + rec).status, 0);
  const std::string common = " --size 320x180 --no-hud --contacts --forces --joint-errors -q";
  auto r = runSubstep("render " + rec + " -o " + (dir / "replayed.png").string() + " --at 0.5" + common);
  ASSERT_EQ(r.status, 0) << r.output;
  r = runSubstep("render assets/scenes/ragdoll.json -o " + (dir / "stepped.png").string() + " --at 0.5" + common);
  ASSERT_EQ(r.status, 0) << r.output;
  auto bytes = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_GT(fs::file_size(dir / "replayed.png"), 1000u);
  EXPECT_EQ(bytes(dir / "replayed.png"), bytes(dir / "stepped.png"));
  r = runSubstep("render assets/scenes/ragdoll.json -o " + (dir / "later.png").string() + " --at 0.8" + common);
  EXPECT_NE(bytes(dir / "later.png"), bytes(dir / "stepped.png"));  // the comparison can tell frames apart

  // A sequence covers the recording: 1 s at 10 fps.
  r = runSubstep("render " + rec + " -o " + (dir / "seq").string() + "/ --fps 10" + common);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(std::distance(fs::directory_iterator(dir / "seq"), fs::directory_iterator()), 10);

  // Damaged: truncated, then a settings option given to a recording.
  const std::string whole = bytes(rec);
  const std::string cut = (dir / "cut.rec").string();
  std::ofstream(cut, std::ios::binary) << whole.substr(0, whole.size() / 2);
  r = runSubstep("render " + cut + " -o " + (dir / "cut.png").string() + " --at 0.5 -q");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find(cut + ": truncated at byte"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "cut.png"));
  r = runSubstep("render " + rec + " -o " + (dir / "x.png").string() + " --kappa 0.5 -q");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("replays the settings it was recorded with"), std::string::npos) << r.output;
}

// `render --record`: every panel of a comparison recorded as it is drawn, each panel's frames the
// states of a World stepped with that panel's settings, bit for bit.
TEST(RecordingCli, RenderRecordsEveryPanel) {
  const fs::path dir = scratch();
  const std::string rec = (dir / "c.rec").string();
  const auto r = runSubstep("render assets/scenes/stack.json --compare a2,a5 --seconds 0.5 --fps 10 --size 160x90 -q -o " +
                            (dir / "frames").string() + "/ --record " + rec + " --record-every 4");
  ASSERT_EQ(r.status, 0) << r.output;
  const Recording file = readRecording(rec);
  ASSERT_EQ(file.panels.size(), 2u);
  const Scene sc = scene("stack");
  for (size_t p = 0; p < 2; ++p) {
    const SolverSettings s = resolvedFromJson(file.meta["panels"][p]["settings"], "panels");
    World w(sc.model, s, sc.initial);
    const std::vector<Snapshot>& frames = file.panels[p];
    ASSERT_GE(frames.size(), 3u);
    EXPECT_EQ(frames[0].state.step, 0);
    EXPECT_EQ(frames[1].state.step, 4);
    for (const Snapshot& f : frames) {
      while (w.state().step < f.state.step) w.step();
      ASSERT_EQ(f.state.bodies.size(), w.state().bodies.size());
      for (size_t b = 0; b < f.state.bodies.size(); ++b)
        ASSERT_EQ(std::memcmp(f.state.bodies[b].x.data(), w.state().bodies[b].x.data(), 3 * sizeof(double)), 0)
            << "panel " << p << " step " << f.state.step;
    }
  }
  EXPECT_EQ(file.meta["panels"][0]["method"], "a2");
  EXPECT_FALSE(fs::exists(rec + ".part" + std::to_string(0)));
  const auto again = runSubstep("render " + rec + " -o x.png --record " + (dir / "d.rec").string());
  EXPECT_EQ(again.status, 2) << again.output;
}
