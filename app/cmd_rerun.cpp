// substep rerun: runs a record again and says whether it is the same to the last bit
// (lab/rerun.h). A record is `substep run --metrics`'s JSON, or a line of a sweep's or the
// atlas's JSONL. Exit status: 0 every record re-run is the same, 1 one differs (the message names
// its first different step and bodies), 2 a record lacks what a re-run needs, or its scene is
// gone or changed.
#include "app/commands.h"
#include "app/common.h"
#include "lab/rerun.h"

#include <nlohmann/json.hpp>

#include <fstream>
#include <iostream>
#include <sstream>

namespace substep::app {

namespace {

using json = nlohmann::json;

struct RerunOptions {
  std::string record;
  std::optional<long long> line;
  std::optional<std::string> key;
  bool quiet = false;
};

// The records of a file: one JSON object, or one per line (JSONL), each named for messages.
std::vector<std::pair<std::string, json>> readRecords(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw UsageError(path + ": cannot open");
  std::stringstream text;
  text << in.rdbuf();
  const std::string all = text.str();
  std::vector<std::pair<std::string, json>> out;
  try {
    const json j = json::parse(all);
    if (!j.is_object()) throw UsageError(path + ": expected a record (a JSON object) or JSON lines of them");
    out.emplace_back(path, j);
    return out;
  } catch (const json::exception&) {
  }
  std::istringstream lines(all);
  std::string l;
  for (long long n = 1; std::getline(lines, l); ++n) {
    if (l.find_first_not_of(" \t\r") == std::string::npos) continue;
    try {
      out.emplace_back(path + " line " + std::to_string(n), json::parse(l));
    } catch (const json::exception& e) {
      throw UsageError(path + " line " + std::to_string(n) + ": not a JSON record: " + e.what());
    }
  }
  if (out.empty()) throw UsageError(path + ": no records in it");
  return out;
}

}  // namespace

void addRerunCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<RerunOptions>();
  CLI::App* cmd = app.add_subcommand("rerun", "Run a record again and check it is the same to the last bit");
  cmd->footer(
      "\nRECORD: `substep run --metrics` JSON, a sweep's JSONL (every line, or --line / --key) or an atlas's\n"
      "atlas.jsonl. Each names its scene (checked against its content hash), every setting, the steps it took and\n"
      "the hashes of its states. Exit 0: the same; 1: a record differs (the first step and bodies are named);\n"
      "2: a record lacks what a re-run needs, or its scene is gone or changed.");
  cmd->add_option("record", opt->record, "The record file")->required();
  cmd->add_option("--line", opt->line, "Re-run only this line of a JSONL file (from 1)")->check(CLI::Range(1LL, 100000000LL));
  cmd->add_option("--key", opt->key, "Re-run only the record whose key is this (a sweep's run key)");
  cmd->add_flag("--quiet,-q", opt->quiet, "Print only records that differ or cannot be re-run");
  cmd->callback([opt, &action] {
    action = [opt] {
      std::vector<std::pair<std::string, json>> records = readRecords(opt->record);
      if (opt->line) {
        if (*opt->line > static_cast<long long>(records.size()))
          throw UsageError("--line " + std::to_string(*opt->line) + ": " + opt->record + " holds " +
                           std::to_string(records.size()) + " records");
        records = {records[static_cast<size_t>(*opt->line - 1)]};
      }
      if (opt->key) {
        std::vector<std::pair<std::string, json>> picked;
        for (auto& r : records)
          if (r.second.value("key", "") == *opt->key) picked.push_back(r);
        if (picked.empty()) throw UsageError("--key: no record of " + opt->record + " has the key \"" + *opt->key + "\"");
        records = picked;
      }
      int same = 0, differ = 0, incomplete = 0;
      InterruptGuard interrupt;
      for (const auto& [where, record] : records) {
        if (InterruptGuard::interrupted()) throw Interrupted();
        std::optional<Progress> bar;
        const lab::RerunReport r = lab::rerunRecord(record, where, [&](long long done, long long steps) {
          if (!bar) bar.emplace("rerun", steps, !opt->quiet);
          bar->update(done);
        });
        if (bar) bar->clear();
        const std::string name = records.size() > 1 ? where + ": " : "";
        switch (r.result) {
          case lab::RerunReport::Result::Same:
            ++same;
            if (!opt->quiet) std::cout << "same      " << name << r.text << "\n";
            break;
          case lab::RerunReport::Result::Differs:
            ++differ;
            std::cout << "DIFFERS   " << name << r.text << "\n";
            break;
          case lab::RerunReport::Result::Incomplete:
            ++incomplete;
            std::cerr << "substep rerun: " << r.text << "\n";
            break;
        }
      }
      if (records.size() > 1 && !opt->quiet)
        std::cout << same << " of " << records.size() << " records the same, " << differ << " differ, " << incomplete
                  << " cannot be re-run\n";
      if (incomplete) return kExitBadInput;
      return differ ? kExitFailure : 0;
    };
  });
}

}  // namespace substep::app
