#include "lab/rerun.h"

#include "lab/peers.h"
#include "lab/provenance.h"
#include "lab/record.h"
#include "physics/run.h"
#include "physics/scene_file.h"
#include "physics/settings_json.h"
#include "physics/state_hash.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>

namespace substep::lab {

namespace {

using json = nlohmann::json;
using Result = RerunReport::Result;

struct Incomplete : std::runtime_error {
  using std::runtime_error::runtime_error;
};

const json& need(const json& r, const char* key, const std::string& where) {
  if (!r.is_object() || !r.contains(key) || r.at(key).is_null())
    throw Incomplete(where + ": the record has no \"" + key +
                     "\", so it cannot be re-run; run the command that made it again for a complete record");
  return r.at(key);
}

std::string text(const json& r, const char* key, const std::string& where) {
  const json& v = need(r, key, where);
  if (!v.is_string()) throw Incomplete(where + ": \"" + key + "\" is not a string");
  return v.get<std::string>();
}

long long integer(const json& r, const char* key, const std::string& where) {
  const json& v = need(r, key, where);
  if (!v.is_number_integer() || v.get<long long>() < 0) throw Incomplete(where + ": \"" + key + "\" is not a count");
  return v.get<long long>();
}

// The scene the record names, where it was given or at its absolute path, with its content as it
// was.
Scene sceneOf(const json& r, const std::string& where) {
  const std::string given = text(r, "scene_file", where);
  const std::string absolute = r.contains("scene_path") && r["scene_path"].is_string() ? r["scene_path"].get<std::string>() : "";
  const std::string hash = text(r, "scene_hash", where);
  std::error_code ec;
  std::string path = given;
  if (!std::filesystem::is_regular_file(path, ec)) path = absolute;
  if (path.empty() || !std::filesystem::is_regular_file(path, ec))
    throw Incomplete(where + ": its scene " + given + (absolute.empty() || absolute == given ? "" : " (" + absolute + ")") +
                     " is gone");
  SceneLimits lim;
  lim.maxBodies = limits::kMaxBodiesCeiling;
  Scene s;
  try {
    s = loadScene(path, lim);
  } catch (const SceneError& e) {
    throw Incomplete(where + ": its scene no longer loads: " + e.what());
  }
  if (s.hash != hash)
    throw Incomplete(where + ": its scene " + path + " changed since the record was made (content hash " + s.hash +
                     ", the record's " + hash + ")");
  return s;
}

class Progress final : public RunObserver {
 public:
  Progress(const std::function<void(long long, long long)>& f, long long steps) : f_(f), steps_(steps) {}
  void observe(const Engine&, const StepRecord& r) override {
    if (f_ && (r.step % 16 == 0 || r.step == steps_)) f_(r.step, steps_);
  }

 private:
  const std::function<void(long long, long long)>& f_;
  long long steps_;
};

std::string bodyList(const Scene& scene, const std::vector<int>& bodies) {
  std::string s;
  for (size_t k = 0; k < bodies.size() && k < 3; ++k)
    s += (k ? ", " : "") + scene.model.bodies[static_cast<size_t>(bodies[k])].name;
  if (bodies.size() > 3) s += " and " + std::to_string(bodies.size() - 3) + " more";
  return s;
}

// Where the re-run first leaves the record: the first kept step whose hash differs, and the bodies
// that differ at the first body checkpoint at or after the step before it.
std::string firstDifference(const Scene& scene, const RunHashes& want, const RunHashes& got, double dt) {
  long long before = 0, at = -1;
  for (const auto& [kept, hash] : want.steps) {
    const long long step = kept;  // a lambda may not capture a structured binding (C++17)
    const auto it = std::find_if(got.steps.begin(), got.steps.end(), [&](const auto& p) { return p.first == step; });
    if (it == got.steps.end() || it->second != hash) {
      at = step;
      break;
    }
    before = step;
  }
  if (at < 0) return "";
  char t[64];
  std::snprintf(t, sizeof t, "%.3f", static_cast<double>(at) * dt);
  std::string s = at == before + 1 ? "first differs at step " + std::to_string(at) + " (t = " + t + " s)"
                                   : "first differs after step " + std::to_string(before) + ", by step " +
                                         std::to_string(at) + " (t = " + t + " s; the record kept every " +
                                         std::to_string(want.every) + "-th step's hash)";
  for (const auto& [kept, hashes] : want.bodies) {
    const long long step = kept;
    if (step <= before) continue;
    const auto it = std::find_if(got.bodies.begin(), got.bodies.end(), [&](const auto& p) { return p.first == step; });
    if (it == got.bodies.end() || it->second.size() != hashes.size()) break;
    std::vector<int> differ;
    for (size_t k = 0; k < hashes.size(); ++k)
      if (hashes[k] != it->second[k]) differ.push_back(got.dynamic[k]);
    if (differ.empty()) continue;
    const std::string who = differ.size() > 1 ? "bodies " + bodyList(scene, differ) + " differ" : "body " + bodyList(scene, differ) + " differs";
    s += step == at ? ": " + who : "; at step " + std::to_string(step) + " " + who;
    break;
  }
  return s;
}

}  // namespace

RerunReport rerunRecord(const json& r, const std::string& where, const std::function<void(long long, long long)>& progress) {
  RerunReport out;
  try {
    const Scene scene = sceneOf(r, where);
    const std::string engineName = text(r, "engine", where);
    const json& settings = need(r, "settings", where);
    const long long steps = integer(r, "steps", where), done = integer(r, "steps_done", where);
    const std::optional<uint64_t> last = parseHash(text(r, "state_hash", where));
    if (!last) throw Incomplete(where + ": \"state_hash\" is not a hash of 16 hex digits");
    RunHashes want;
    try {
      want = hashesFromJson(need(r, "state_hashes", where));
    } catch (const std::invalid_argument& e) {
      throw Incomplete(where + ": " + e.what());
    }

    std::unique_ptr<World> world;
    std::unique_ptr<Engine> engine;
    double dt = 0;
    std::string line;
    if (engineName == "substep") {
      SolverSettings s;
      try {
        s = resolvedFromJson(settings, where + ": settings");
      } catch (const std::invalid_argument& e) {
        throw Incomplete(e.what());
      }
      world = std::make_unique<World>(scene.model, s, scene.initial);
      engine = std::make_unique<WorldEngine>(*world);
      dt = s.dt;
      line = settingsLine(s, LineDetail::Brief);
    } else if (findPeer(engineName)) {
      PeerSettings p;
      try {
        p = peerSettingsFromJson(engineName, settings, where + ": settings");
      } catch (const std::invalid_argument& e) {
        throw Incomplete(e.what());
      }
      dt = p.dt;
      const std::string why = peerUnsupported(engineName, scene.model, scene.initial);
      if (!why.empty()) throw Incomplete(where + ": no " + peerDisplayName(engineName) + " peer for the scene: " + why);
      engine = makePeerEngine(p, scene.model, scene.initial);
      line = peerLine(p);
    } else {
      throw Incomplete(where + ": engine \"" + engineName + "\": expected substep, bullet, ode or mujoco");
    }

    // A refused record is re-run to its refusal: the same step must refuse again.
    const bool refused = r.value("refused", false);
    StateHashes hashes(scene.model, steps, want.every);
    Progress bar(progress, done);
    RunDriver run(*engine, refused ? steps : done);
    run.add(hashes).add(bar);
    const RunOutcome& o = run.run();
    const RunHashes& got = hashes.hashes();
    const std::string what = scene.file + " under " + line + ", " + std::to_string(done) + " steps";
    const std::string commit = r.contains("commit") && r["commit"].is_string() ? r["commit"].get<std::string>() : "?";
    const std::string built = commit == sourceCommit() ? "" : " (recorded at " + commit + ", re-run at " + sourceCommit() + ")";
    if (refused != (o.end == RunOutcome::End::Refused)) {
      out.result = Result::Differs;
      out.text = what + ": " + (refused ? "the record was refused at step " + std::to_string(done + 1) + ", the re-run was not"
                                        : "the re-run was refused: " + o.message) + built;
      return out;
    }
    if (o.steps != done) {
      out.result = Result::Differs;
      out.text = what + ": the re-run ended at step " + std::to_string(o.steps) + " (" + o.message + "); the record went to step " +
                 std::to_string(done) + built;
      return out;
    }
    const std::string diff = firstDifference(scene, want, got, dt);
    if (diff.empty() && got.last == *last && refused) {
      out.result = Result::Same;
      out.text = scene.file + " under " + line + ": refused again at step " + std::to_string(done + 1) + ", as the record (" +
                 o.message + ")" + built;
    } else if (diff.empty() && got.last == *last) {
      out.result = Result::Same;
      out.text = what + ": the same, bit for bit (state hash " + hashText(got.last) + " at step " + std::to_string(done) + ")" + built;
    } else {
      out.result = Result::Differs;
      out.text = what + ": " + (diff.empty() ? "the last state differs" : diff) + " (state hash " + hashText(got.last) +
                 ", the record's " + hashText(*last) + ")" + built;
    }
  } catch (const Incomplete& e) {
    out.result = Result::Incomplete;
    out.text = e.what();
  } catch (const std::invalid_argument& e) {  // settings a World refuses
    out.result = Result::Incomplete;
    out.text = where + ": " + e.what();
  }
  return out;
}

}  // namespace substep::lab
