// Solver settings as JSON, by the schema's keys (physics/settings.h): what every record, the
// run metrics, the bench and the server write, and what `substep rerun` reads back. Numbers as
// numbers, flags as true/false, choices by name; a value written is read back the same.
#pragma once

#include "physics/settings.h"

#include <nlohmann/json.hpp>

#include <string>

namespace substep {

// Every resolved setting, in the table's order.
nlohmann::json settingsJson(const SolverSettings& s);
// The same for given settings: only those set.
nlohmann::json overridesJson(const SolverOverrides& o);
// Given settings from such an object (or a scene's "solver" block). Unknown keys and wrong types
// are refused: std::invalid_argument "<where>.<key>: expected ..., got ...".
SolverOverrides overridesFromJson(const nlohmann::json& j, const std::string& where);
// Resolved settings from settingsJson()'s object, each field as it is (whether or not the algorithm
// reads it), so that a record's settings are the run's to the last bit. Every key must be there:
// std::invalid_argument "<where>: no <key>" otherwise, or naming a malformed value.
SolverSettings resolvedFromJson(const nlohmann::json& j, const std::string& where);
// One setting's value as JSON, and back (checked).
nlohmann::json settingJson(const SettingSpec& s, double value);
double settingFromJson(const SettingSpec& s, const nlohmann::json& v);  // throws std::invalid_argument

// The schema itself, for /api/methods and the page: per setting its key, alias, flag, kind,
// range or choices, which algorithms read it, its origin, its default per algorithm, help and
// the page's control.
nlohmann::json schemaJson();

}  // namespace substep
