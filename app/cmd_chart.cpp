// substep chart: a sweep's records as charts, drawn by gnuplot (PNG and SVG). The charts and
// their data come from lab/chart.h; this command writes them and runs gnuplot.
#include "app/chart_files.h"
#include "app/commands.h"
#include "app/common.h"
#include "lab/sweep.h"

#include <algorithm>
#include <filesystem>
#include <iostream>

namespace substep::app {

namespace {

struct ChartCmdOptions {
  std::string input, output, error;
  bool quiet = false;
};

}  // namespace

void addChartCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<ChartCmdOptions>();
  CLI::App* cmd = app.add_subcommand("chart", "Draw a sweep's records with gnuplot: error against cost, sub-steps against "
                                              "iterations, A3/A4/A5, convergence in h (PNG and SVG)");
  cmd->footer("\nPer scene: SCENE-pareto (every method family a series, the Pareto front), SCENE-substeps, SCENE-havok,\n"
              "SCENE-convergence where the records hold what each needs. The data and gnuplot scripts are kept in DIR/data/\n"
              "(cd DIR && gnuplot data/NAME.gp redraws one). Needs gnuplot (Debian: gnuplot-nox); $SUBSTEP_GNUPLOT overrides.");
  cmd->add_option("records", opt->input, "A sweep's output (JSONL)")->required();
  cmd->add_option("-o,--output", opt->output,
                  "The folder the charts are written to (default: beside the records, named after them: s.jsonl -> s-charts/)");
  cmd->add_option("--error", opt->error, "The quantity drawn as error (default: each scene's, as the records say): one of " + [] {
    std::string s;
    for (const std::string& m : criterionMetrics()) s += (s.empty() ? "" : ", ") + m;
    return s;
  }());
  cmd->add_flag("--quiet,-q", opt->quiet, "Print nothing but errors");
  cmd->callback([opt, &action] {
    action = [opt] {
      if (!opt->error.empty()) {
        const auto& names = criterionMetrics();
        if (std::find(names.begin(), names.end(), opt->error) == names.end())
          throw UsageError("--error: unknown quantity \"" + opt->error + "\"; see --help");
      }
      if (const std::string why = checkInputFile(opt->input, size_t(1) << 34); !why.empty())
        throw UsageError(opt->input + ": " + why);
      std::vector<nlohmann::json> rows;
      try {
        rows = lab::readRows(opt->input);
      } catch (const std::runtime_error& e) {
        throw UsageError(e.what());
      }
      if (rows.empty()) throw UsageError(opt->input + ": no records to chart");
      if (opt->output.empty()) {
        const std::filesystem::path in(opt->input);
        opt->output = (in.parent_path() / (in.stem().string() + "-charts")).string();
      }
      lab::ChartOptions co;
      co.error = opt->error;
      const std::vector<std::string> written = writeCharts(rows, co, opt->output, opt->quiet);
      if (!opt->quiet) std::cout << "wrote     " << written.size() << " files in " << opt->output << "\n";
      return 0;
    };
  });
}

}  // namespace substep::app
