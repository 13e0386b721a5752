#include "lab/sweep.h"

#include "lab/record.h"
#include "physics/scene_file.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

namespace substep::lab {

namespace {

using json = nlohmann::json;

[[noreturn]] void bad(const std::string& file, const std::string& path, const std::string& what) {
  throw std::invalid_argument(file + ": " + (path.empty() ? "" : path + ": ") + what);
}

std::vector<std::string> strings(const json& v, const std::string& file, const std::string& key) {
  std::vector<std::string> out;
  if (v.is_string()) return {v.get<std::string>()};
  if (!v.is_array() || v.empty()) bad(file, key, "expected a string or a non-empty array of strings");
  for (size_t i = 0; i < v.size(); ++i) {
    if (!v[i].is_string()) bad(file, key + "[" + std::to_string(i) + "]", "expected a string");
    out.push_back(v[i].get<std::string>());
  }
  return out;
}

// FNV-1a, 64 bits, as hex: a plan's identity from its keys.
std::string hashText(const std::string& s) {
  unsigned long long h = 1469598103934665603ULL;
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  char buf[20];
  std::snprintf(buf, sizeof buf, "%016llx", h);
  return buf;
}

}  // namespace

double parseStep(const std::string& text) {
  return findSetting("dt")->parse(text);  // throws "expected a number in [1e-6, 1], got ..."
}

SweepSpec readSweepSpec(const std::string& file) {
  std::string text;
  try {
    text = readInputFile(file, limits::kMaxSceneBytes);
  } catch (const SceneError& e) {
    throw std::invalid_argument(e.what());
  }
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    bad(file, "", std::string("not JSON: ") + e.what());
  }
  if (!j.is_object()) bad(file, "", "expected an object {\"scenes\": [...], \"methods\": [...]}");
  SweepSpec s;
  for (const auto& [key, v] : j.items()) {
    if (key == "scenes") {
      s.scenes = strings(v, file, key);
    } else if (key == "methods") {
      s.methods = strings(v, file, key);
      for (size_t i = 0; i < s.methods.size(); ++i) try {
          parseMethods(s.methods[i]);
        } catch (const std::invalid_argument& e) {
          bad(file, "methods[" + std::to_string(i) + "]", e.what());
        }
    } else if (key == "dt") {
      const json list = v.is_array() ? v : json::array({v});
      for (size_t i = 0; i < list.size(); ++i) try {
          s.dts.push_back(list[i].is_number() ? parseStep(numberText(list[i].get<double>()))
                                              : parseStep(list[i].is_string() ? list[i].get<std::string>() : "?"));
        } catch (const std::invalid_argument& e) {
          bad(file, "dt[" + std::to_string(i) + "]", e.what());
        }
    } else if (key == "repeat") {
      if (!v.is_number_integer() || v.get<long long>() < 1 || v.get<long long>() > 1000)
        bad(file, key, "expected an integer in [1, 1000], got " + v.dump());
      s.repeat = v.get<int>();
    } else if (key == "seconds") {
      if (!v.is_number() || !(v.get<double>() > 0) || v.get<double>() > 3600)
        bad(file, key, "expected a number in (0, 3600], got " + v.dump());
      s.seconds = v.get<double>();
    } else if (key == "reference") {
      if (!v.is_object()) bad(file, key, "expected an object, as a scene's criteria.reference");
      s.reference = v;
    } else {
      bad(file, "", "unknown key \"" + key + "\" (expected one of: scenes, methods, dt, repeat, seconds, reference)");
    }
  }
  if (s.scenes.empty()) bad(file, "", "missing required field \"scenes\"");
  if (s.methods.empty()) bad(file, "", "missing required field \"methods\"");
  return s;
}

Scene loadSweepScene(const std::string& path, const std::optional<json>& reference) {
  if (!reference) return loadScene(path);
  const std::string text = readInputFile(path, limits::kMaxSceneBytes);
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception&) {
    return loadScene(path);  // the scene reader says what is wrong, with the line and column
  }
  if (!j.is_object()) return loadScene(path);
  j["criteria"]["reference"] = *reference;
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  return parseScene(j.dump(), path + " (with the sweep's reference)", parent.empty() ? "." : parent.string());
}

SweepPlan planSweep(const SweepSpec& spec, std::vector<Scene> scenes) {
  SweepPlan plan;
  plan.scenes = std::move(scenes);
  std::vector<Method> methods;
  for (const std::string& m : spec.methods) {
    const std::vector<Method> e = parseMethods(m);
    methods.insert(methods.end(), e.begin(), e.end());
  }
  std::vector<std::optional<double>> dts;
  for (double d : spec.dts) dts.push_back(d);
  if (dts.empty()) dts.push_back(std::nullopt);
  std::string keys;
  std::set<std::string> seen;
  for (size_t s = 0; s < plan.scenes.size(); ++s) {
    const Scene& scene = plan.scenes[s];
    const double seconds = spec.seconds ? *spec.seconds : scene.criteria ? scene.criteria->seconds : 3.0;
    for (const Method& m : methods)
      for (const std::optional<double>& dt : dts) {
        PlannedRun r;
        r.scene = s;
        r.method = m;
        r.dt = m.overrides.get(&SolverSettings::dt) ? std::nullopt : dt;  // a method that names its h keeps it
        r.seconds = seconds;
        SolverSettings settings;
        try {
          settings = methodSettings(m, scene, r.dt);
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument(sceneName(scene) + ", " + m.text + ": " + e.what());
        }
        r.key = runKey(scene, m.text, settings.dt, seconds);
        if (!seen.insert(r.key).second) continue;  // the same run named twice
        keys += r.key + "\n";
        plan.runs.push_back(r);
      }
  }
  plan.id = hashText(keys);
  return plan;
}

Shard parseShard(const std::string& text) {
  Shard s;
  const size_t slash = text.find('/');
  auto whole = [&](const std::string& t, int& out) {
    if (t.empty() || t.size() > 6 || t.find_first_not_of("0123456789") != std::string::npos) return false;
    out = std::stoi(t);
    return true;
  };
  if (slash == std::string::npos || !whole(text.substr(0, slash), s.index) || !whole(text.substr(slash + 1), s.count) ||
      s.count < 1 || s.index < 1 || s.index > s.count)
    throw std::invalid_argument("expected i/N with 1 <= i <= N (shard i of N), e.g. 2/4; got \"" + text + "\"");
  return s;
}

std::vector<json> readRows(const std::string& file, bool* truncated) {
  if (truncated) *truncated = false;
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file + ": cannot open");
  std::stringstream buf;
  buf << in.rdbuf();
  const std::string text = buf.str();
  std::vector<json> rows;
  size_t start = 0, line = 0;
  while (start < text.size()) {
    const size_t end = text.find('\n', start);
    const bool last = end == std::string::npos;
    const std::string l = text.substr(start, last ? std::string::npos : end - start);
    ++line;
    start = last ? text.size() : end + 1;
    if (l.find_first_not_of(" \t\r") == std::string::npos) continue;
    json j;
    try {
      j = json::parse(l);
    } catch (const json::exception&) {
      if (last && truncated) {  // written in part when the sweep stopped
        *truncated = true;
        break;
      }
      throw std::runtime_error(file + ":" + std::to_string(line) + ": not a JSON record (a sweep's output has one per line)");
    }
    if (!j.is_object() || !j.contains("key") || !j["key"].is_string())
      throw std::runtime_error(file + ":" + std::to_string(line) + ": a record without a \"key\"; is this a sweep's output?");
    if (last && truncated) *truncated = true;  // complete JSON but no newline: rewritten with one
    rows.push_back(std::move(j));
  }
  return rows;
}

MergeResult mergeRows(const std::vector<std::vector<json>>& files) {
  MergeResult out;
  std::set<std::string> keys;
  struct Placed {
    std::string plan;
    long long index;
    json row;
  };
  std::vector<Placed> placed;
  std::vector<json> loose;
  std::map<std::string, long long> runs;              // plan -> its run count
  std::map<std::string, std::set<long long>> present;  // plan -> indices
  for (const auto& rows : files)
    for (const json& r : rows) {
      const std::string key = r["key"].get<std::string>();
      if (!keys.insert(key).second) {
        out.duplicates.push_back(key);
        continue;
      }
      if (r.contains("sweep") && r["sweep"].is_object()) {
        const json& s = r["sweep"];
        const std::string plan = s.value("plan", "");
        const long long index = s.value("index", -1LL);
        runs[plan] = std::max(runs[plan], s.value("runs", 0LL));
        present[plan].insert(index);
        placed.push_back({plan, index, r});
      } else {
        loose.push_back(r);
      }
    }
  std::stable_sort(placed.begin(), placed.end(),
                   [](const Placed& a, const Placed& b) { return a.plan != b.plan ? a.plan < b.plan : a.index < b.index; });
  for (Placed& p : placed) out.rows.push_back(std::move(p.row));
  for (json& r : loose) out.rows.push_back(std::move(r));
  for (const auto& [plan, n] : runs) {
    std::string missing;
    long long count = 0;
    for (long long k = 0; k < n; ++k)
      if (!present[plan].count(k)) {
        if (count < 20) missing += (count ? ", " : "") + std::to_string(k + 1);
        ++count;
      }
    if (count)
      out.gaps.push_back("plan " + plan + ": " + std::to_string(count) + " of " + std::to_string(n) + " runs missing (" +
                         missing + (count > 20 ? ", ..." : "") + ")");
  }
  return out;
}

}  // namespace substep::lab
