#include "physics/settings_json.h"

#include "physics/utf8.h"

#include <stdexcept>

namespace substep {

using json = nlohmann::json;

namespace {

const char* kindName(SettingKind k) {
  switch (k) {
    case SettingKind::Integer: return "integer";
    case SettingKind::Real: return "number";
    case SettingKind::Flag: return "flag";
    case SettingKind::Choice: return "choice";
  }
  return "?";
}

// The value as the message quotes it: its JSON, cut short (invalid UTF-8 replaced, so that the
// message itself is valid JSON text).
std::string typeOf(const json& v) {
  return messageValue(v.dump(-1, ' ', false, json::error_handler_t::replace));
}

}  // namespace

json settingJson(const SettingSpec& s, double v) {
  switch (s.kind) {
    case SettingKind::Integer: return static_cast<long long>(v);
    case SettingKind::Real: return v;
    case SettingKind::Flag: return v != 0;
    case SettingKind::Choice: return s.text(v);
  }
  return nullptr;
}

double settingFromJson(const SettingSpec& s, const json& v) {
  switch (s.kind) {
    case SettingKind::Integer:
    case SettingKind::Real:
      if (!v.is_number()) throw std::invalid_argument("expected " + s.expected() + ", got " + typeOf(v));
      return s.check(v.get<double>());
    case SettingKind::Flag:
      if (!v.is_boolean()) throw std::invalid_argument("expected true or false, got " + typeOf(v));
      return v.get<bool>() ? 1 : 0;
    case SettingKind::Choice:
      if (!v.is_string()) throw std::invalid_argument("expected " + s.expected() + ", got " + typeOf(v));
      return s.parse(v.get<std::string>());
  }
  return 0;
}

json settingsJson(const SolverSettings& s) {
  json j = json::object();
  for (const SettingSpec& spec : settingTable())
    if (spec.resolved()) j[spec.key] = settingJson(spec, spec.get(s));
  return j;
}

json overridesJson(const SolverOverrides& o) {
  json j = json::object();
  for (const SettingSpec& spec : settingTable())
    if (o.has(spec)) j[spec.key] = settingJson(spec, *o.value(spec));
  return j;
}

SolverOverrides overridesFromJson(const json& j, const std::string& where) {
  if (!j.is_object()) throw std::invalid_argument(where + ": expected an object of settings, got " + typeOf(j));
  SolverOverrides o;
  for (const auto& [key, v] : j.items()) {
    const SettingSpec* s = findSetting(key);
    if (!s || key != s->key)
      throw std::invalid_argument(where + "." + utf8Prefix(key, limits::kMaxMessageValue) +
                                  ": unknown setting; expected one of algorithm, " + settingKeys());
    try {
      o.set(*s, settingFromJson(*s, v));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(where + "." + key + ": " + e.what());
    }
  }
  return o;
}

SolverSettings resolvedFromJson(const json& j, const std::string& where) {
  if (!j.is_object()) throw std::invalid_argument(where + ": expected an object of settings, got " + typeOf(j));
  SolverSettings s;
  for (const SettingSpec& spec : settingTable()) {
    if (!spec.resolved()) continue;
    if (!j.contains(spec.key)) {
      // Records and recordings written before these settings existed ran on one thread, uncoloured.
      if (spec.field == SettingField(&SolverSettings::threads) || spec.field == SettingField(&SolverSettings::colours)) {
        spec.put(s, spec.defaultFor(Algorithm::A2));
        continue;
      }
      throw std::invalid_argument(where + ": no " + spec.key);
    }
    try {
      spec.put(s, settingFromJson(spec, j.at(spec.key)));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(where + "." + spec.key + ": " + e.what());
    }
  }
  return s;
}

json schemaJson() {
  json list = json::array();
  for (const SettingSpec& s : settingTable()) {
    json takes = json::array(), defaults = json::object();
    for (Algorithm a : kAlgorithms) {
      if (s.takes.has(a)) takes.push_back(algorithmName(a));
      defaults[algorithmName(a)] = s.resolved() ? settingJson(s, s.defaultFor(a)) : json(nullptr);
    }
    json j = {{"key", s.key},       {"alias", s.alias},       {"flag", s.flag},
              {"kind", kindName(s.kind)}, {"help", s.help},   {"expected", s.expected()},
              {"takes", takes},     {"origin", originName(s.origin)}, {"defaults", defaults},
              {"resolved", s.resolved()}};
    if (s.kind == SettingKind::Integer || s.kind == SettingKind::Real)
      j["range"] = {{"min", s.range.lo}, {"max", s.range.hi}, {"min_open", s.range.loOpen}, {"max_open", s.range.hiOpen}};
    if (s.kind == SettingKind::Choice) j["choices"] = s.choices;
    j["control"] = {{"main", s.control.main}, {"label", s.control.label[0] ? s.control.label : s.key}};
    if (s.control.max > s.control.min)
      j["control"]["slider"] = {{"min", s.control.min}, {"max", s.control.max}, {"step", s.control.step}};
    list.push_back(j);
  }
  return list;
}

}  // namespace substep
