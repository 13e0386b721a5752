#include "lab/atlas.h"

#include "lab/record.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace substep::lab {

const char* defaultAtlasMethods() {
  return "a1,a2:m=4,a2:m=10,a3:preset=4-medium,a4:preset=4-medium,a5:preset=4-medium,soft,bullet:it=10,ode:it=20,mujoco";
}

std::vector<std::string> atlasScenes(const std::string& folder) {
  namespace fs = std::filesystem;
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(folder, ec))
    if (e.path().extension() == ".json") out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<AtlasCell> runAtlasScene(const Scene& scene, const std::vector<Method>& methods, double frameRate, int repeat,
                                     const std::string& recordDir, bool verdictsOnly) {
  const double seconds = scene.criteria ? scene.criteria->seconds : 3;
  std::optional<PreparedReference> reference;
  if (scene.criteria && scene.criteria->reference) reference = prepareReference(scene, *scene.criteria->reference, seconds);
  std::vector<AtlasCell> cells;
  for (const Method& m : methods) {
    RunSetup setup;
    setup.seconds = seconds;
    setup.frameRate = frameRate;
    setup.repeat = repeat;
    setup.reference = reference ? &*reference : nullptr;
    if (verdictsOnly && scene.criteria)
      setup.stop = [&scene](const Metrics& m, double) { return boundMissed(*scene.criteria, m); };
    if (!recordDir.empty()) setup.recording = (std::filesystem::path(recordDir) / recordingFileName(scene, m.text)).string();
    const auto t0 = std::chrono::steady_clock::now();
    AtlasCell c;
    c.run = runMethod(scene, m, setup);
    c.wallSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    c.verdict = judge(scene, c.run);
    cells.push_back(std::move(c));
  }
  return cells;
}

VerdictTable readVerdicts(const std::string& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file + ": cannot open the expected verdicts");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(file + ": not JSON: " + e.what());
  }
  VerdictTable t;
  if (!j.is_object() || !j.contains("verdicts") || !j["verdicts"].is_object())
    throw std::runtime_error(file + ": expected {\"verdicts\": {scene: {method: verdict}}}");
  for (const auto& [scene, row] : j["verdicts"].items()) {
    if (!row.is_object()) throw std::runtime_error(file + ": verdicts." + scene + ": expected an object");
    for (const auto& [method, v] : row.items()) {
      if (!v.is_string()) throw std::runtime_error(file + ": verdicts." + scene + "." + method + ": expected a string");
      t[scene][method] = v.get<std::string>();
    }
  }
  return t;
}

nlohmann::json verdictsJson(const VerdictTable& t) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [scene, row] : t)
    for (const auto& [method, v] : row) j[scene][method] = v;
  return j;
}

}  // namespace substep::lab
