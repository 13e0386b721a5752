#pragma once

#include <CLI/CLI.hpp>

#include <functional>

namespace substep::app {

// Each adds its subcommand; when the user picks it, its callback stores the work in `action`.
void addRunCommand(CLI::App& app, std::function<int()>& action);
void addScenesCommand(CLI::App& app, std::function<int()>& action);
void addRenderCommand(CLI::App& app, std::function<int()>& action);
void addSnapshotCommand(CLI::App& app, std::function<int()>& action);
void addServeCommand(CLI::App& app, std::function<int()>& action);
void addSweepCommand(CLI::App& app, std::function<int()>& action);
void addChartCommand(CLI::App& app, std::function<int()>& action);
void addAtlasCommand(CLI::App& app, std::function<int()>& action);
void addAdviseCommand(CLI::App& app, std::function<int()>& action);
void addRerunCommand(CLI::App& app, std::function<int()>& action);
void addSettingsCommand(CLI::App& app, std::function<int()>& action);
void addCompareCommand(CLI::App& app, std::function<int()>& action);

}  // namespace substep::app
