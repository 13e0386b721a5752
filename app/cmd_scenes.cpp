// substep scenes: the scene files and the generators, one line each.
#include "app/commands.h"
#include "app/common.h"
#include "physics/generators.h"

#include <algorithm>
#include <filesystem>
#include <iomanip>
#include <iostream>

namespace substep::app {

void addScenesCommand(CLI::App& app, std::function<int()>& action) {
  auto dir = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand("scenes", "List the scene files and the generators scenes can use");
  cmd->add_option("--dir", *dir, "Folder of scene files (default: the assets' scenes/)");
  cmd->callback([dir, &action] {
    action = [dir] {
      namespace fs = std::filesystem;
      const std::string folder = dir->empty() ? assetsDir() + "/scenes" : *dir;
      std::error_code ec;
      if (!fs::is_directory(folder, ec)) throw UsageError(folder + ": not a folder of scene files");
      // Subfolders too (atlas/, reference/), named as `sweep --scenes` takes them: "atlas/card_house".
      std::vector<fs::path> files;
      for (const auto& e : fs::recursive_directory_iterator(folder))
        if (e.path().extension() == ".json") files.push_back(e.path());
      std::sort(files.begin(), files.end(), [&](const fs::path& a, const fs::path& b) {
        const auto depth = [&](const fs::path& p) { return std::distance(p.lexically_relative(folder).begin(), p.lexically_relative(folder).end()); };
        return depth(a) != depth(b) ? depth(a) < depth(b) : a < b;
      });
      std::cout << "Scene files in " << folder << ":\n";
      for (const auto& f : files) {
        std::string line;
        try {
          const Scene s = loadScene(f.string());
          line = s.description.substr(0, s.description.find('\n'));
          line += " [" + std::to_string(s.model.dynamicCount()) + " bodies, " + std::to_string(s.model.joints.size()) +
                  " joints]";
        } catch (const SceneError& e) {
          line = std::string("(does not load: ") + e.what() + ")";
        }
        const fs::path name = f.lexically_relative(folder).replace_extension();
        std::cout << "  " << std::left << std::setw(28) << name.string() << line << "\n";
      }
      std::cout << "Generators (in a scene's \"generators\" list):\n";
      for (const GeneratorInfo& g : generatorList())
        std::cout << "  " << std::left << std::setw(28) << g.type << g.summary << "\n";
      return 0;
    };
  });
}

}  // namespace substep::app
