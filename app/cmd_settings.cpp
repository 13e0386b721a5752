// substep settings: the settings schema (physics/settings.h) as a table, a Markdown table
// (docs/settings.md is this output, checked by a test) or JSON (as /api/methods gives it), so that
// no document lists the settings by hand.
#include "app/commands.h"
#include "app/common.h"
#include "physics/settings_json.h"

#include <iostream>

namespace substep::app {

namespace {

std::string kindText(const SettingSpec& s) {
  switch (s.kind) {
    case SettingKind::Integer: return "integer " + s.range.text();
    case SettingKind::Real: return "number " + s.range.text();
    case SettingKind::Flag: return "flag (`--no-" + std::string(s.flag) + "` turns it off)";
    case SettingKind::Choice: {
      std::string t = "one of ";
      for (size_t i = 0; i < s.choices.size(); ++i) t += (i ? ", " : "") + s.choices[i];
      return t;
    }
  }
  return "";
}

void markdown(std::ostream& o) {
  o << "| key | alias | option | value | read by | origin | default | what it is |\n"
       "|---|---|---|---|---|---|---|---|\n";
  for (const SettingSpec& s : settingTable())
    o << "| `" << s.key << "` | " << (s.alias[0] ? std::string("`") + s.alias + "`" : "") << " | `--" << s.flag << "` | "
      << kindText(s) << " | " << (s.takes.all() ? "all" : s.takes.text()) << " | " << originName(s.origin) << " | "
      << defaultsText(s) << " | " << s.help << " |\n";
}

void plain(std::ostream& o) {
  for (const SettingSpec& s : settingTable()) {
    o << s.key << (s.alias[0] ? std::string(" (") + s.alias + ")" : "") << "  --" << s.flag << "  " << kindText(s) << "\n"
      << "    read by " << (s.takes.all() ? "every algorithm" : s.takes.text()) << "; " << originName(s.origin)
      << "; default " << defaultsText(s) << "\n    " << s.help << "\n";
  }
}

}  // namespace

void addSettingsCommand(CLI::App& app, std::function<int()>& action) {
  auto format = std::make_shared<std::string>("text");
  CLI::App* cmd = app.add_subcommand("settings", "List every solver setting: key, option, range, defaults, help");
  cmd->add_option("--format", *format, "text, markdown (docs/settings.md) or json (as /api/methods)")
      ->check(CLI::IsMember({"text", "markdown", "json"}));
  cmd->callback([format, &action] {
    action = [format] {
      if (*format == "markdown") markdown(std::cout);
      else if (*format == "json") std::cout << schemaJson().dump(1) << "\n";
      else plain(std::cout);
      return 0;
    };
  });
}

}  // namespace substep::app
