// substep: a lab for the sub-stepping constraint solver of "The Sub-stepping of Havok's Physics
// Solver" (Nohra). Thin: every subcommand calls the physics and render libraries.
#include "app/commands.h"
#include "app/common.h"
#include "lab/provenance.h"

#include <iostream>

int main(int argc, char** argv) {
  using namespace substep::app;
  CLI::App app{"substep: step, measure and render the report's Algorithms 1 to 5 on rigid-body scenes"};
  app.require_subcommand(1);
  app.set_version_flag("--version", [] { return "substep " SUBSTEP_VERSION " (commit " + substep::lab::sourceState() + ")"; },
                       "Print the version and the source commit, then exit");
  std::function<int()> action;
  addRunCommand(app, action);
  addScenesCommand(app, action);
  addRenderCommand(app, action);
  addSnapshotCommand(app, action);
  addServeCommand(app, action);
  addSweepCommand(app, action);
  addCompareCommand(app, action);
  addChartCommand(app, action);
  addAtlasCommand(app, action);
  addAdviseCommand(app, action);
  addRerunCommand(app, action);
  addSettingsCommand(app, action);
  return runCommandLine(app, argc, argv, "substep", [&] { return action ? action() : 0; });
}
