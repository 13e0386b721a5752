// substep compare: the engine comparison of Erez, Tassa and Todorov (ICRA 2015) reproduced in one
// command: a sweep (assets/sweeps/compare.json: scenes x methods x time steps) into DIR/compare.jsonl,
// its charts (one `speed` chart per scene: error against the real-time factor, each method a curve
// over h) and the table of who leads where (DIR/table.md). The sweep, charts and table are the
// lab's (lab/sweep.h, lab/chart.h, lab/compare.h); this file strings them together.
#include "app/chart_files.h"
#include "app/commands.h"
#include "app/common.h"
#include "app/sweep_command.h"
#include "lab/compare.h"
#include "lab/sweep.h"

#include <chrono>
#include <filesystem>
#include <iostream>

namespace substep::app {

namespace {

struct CompareOptions {
  SweepOptions sweep;
  std::string folder = "out/compare";
};

int runCompare(CompareOptions o) {
  const auto t0 = std::chrono::steady_clock::now();
  if (o.sweep.spec.empty() && (o.sweep.scenes.empty() || o.sweep.methods.empty()))
    o.sweep.spec = assetsDir() + "/sweeps/compare.json";
  std::filesystem::create_directories(o.folder);
  o.sweep.output = (std::filesystem::path(o.folder) / "compare.jsonl").string();
  if (const int status = runSweep(o.sweep); status != 0) return status;

  std::vector<nlohmann::json> rows;
  try {
    rows = lab::readRows(o.sweep.output);
  } catch (const std::runtime_error& e) {
    throw UsageError(e.what());
  }
  const std::vector<std::string> written = writeCharts(rows, lab::ChartOptions{}, o.folder, o.sweep.quiet);
  const std::string table = lab::comparisonTable(lab::compareRuns(rows));
  const std::string tablePath = (std::filesystem::path(o.folder) / "table.md").string();
  AtomicFile t(tablePath);
  t.out() << "# Who leads where\n\nFrom " << o.sweep.output << " (" << rows.size()
          << " records; each scene's error against its reference, the real-time factor on one core). `substep compare` "
             "wrote it.\n\n"
          << table;
  t.commit();
  if (!o.sweep.quiet) {
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "\n" << table << "\nwrote     " << tablePath << ", " << written.size() << " charts in " << o.folder
              << " (SCENE-speed.png: error against the real-time factor); " << static_cast<int>(s) << " s\n";
  }
  return 0;
}

}  // namespace

void addCompareCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<CompareOptions>();
  CLI::App* cmd = app.add_subcommand(
      "compare", "The engine comparison of Erez, Tassa and Todorov (ICRA 2015): every method over a range of h on each "
                 "scene, error against the real-time factor, charts and a table of who leads where");
  cmd->footer("\nBy default the sweep of assets/sweeps/compare.json (a pendulum, a chain, a pile, the ragdoll pile, a\n"
              "grasp-like stack under A1-A5, the soft step, Bullet, ODE and MuJoCo at h = 1/30 ... 1/240). The records go\n"
              "to DIR/compare.jsonl (a stopped comparison resumes), the charts to DIR/SCENE-speed.png (and the other\n"
              "kinds `substep chart` draws), the table to DIR/table.md. docs/lab.md says what it found.");
  cmd->add_option("spec", opt->sweep.spec, "A sweep spec (JSON); default assets/sweeps/compare.json");
  cmd->add_option("-o,--output", opt->folder, "The folder for the records, charts and table (default out/compare)");
  cmd->add_option("--scenes", opt->sweep.scenes, "Scenes instead of the spec's, comma-separated")->delimiter(',');
  cmd->add_option("--methods", opt->sweep.methods, "Methods instead of the spec's, comma-separated specs")->delimiter(',');
  cmd->add_option("--dt", opt->sweep.dts, "Time steps instead of the spec's, comma-separated (1/30,1/60)")->delimiter(',');
  cmd->add_option("--repeat", opt->sweep.repeat, "Timed runs of each run; the cost is their median (default: the spec's)")
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--seconds", opt->sweep.seconds, "Simulated time of each run [s] (default: the spec's, else each scene's)")
      ->check(finiteIn(1e-3, 1e6));
  cmd->add_flag("--quiet,-q", opt->sweep.quiet, "Print nothing but errors (no progress bar either)");
  addMaxBodies(*cmd, opt->sweep.limits);
  cmd->callback([opt, &action] { action = [opt] { return runCompare(*opt); }; });
}

}  // namespace substep::app
