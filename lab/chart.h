// Charts of sweep records, drawn by gnuplot: this module writes the data and the gnuplot
// scripts (PNG through pngcairo, SVG); `substep chart` runs gnuplot on them. Per scene:
//   pareto       error against cost, log-log, every method family a series, the Pareto front
//   substeps     the report's claim "sub-steps beat micro-iterations at equal work": n sub-steps
//                of 1 iteration against 1 step of n iterations
//   havok        A3 against A4 against A5: error and cost against n
//   convergence  error against h, each method's fitted order (slope) in the legend
//   speed        error against the real-time factor, each method a curve over h (the engine
//                comparison of Erez, Tassa and Todorov, ICRA 2015; `substep compare`)
// A chart is made only where the records hold what it needs (docs/lab.md, "Charts").
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <utility>
#include <vector>

namespace substep::lab {

struct ChartOptions {
  std::string error;     // the quantity drawn as error (criterionMetrics()); "" = each record's "error"
  int width = 960, height = 600;  // PNG pixels (the SVG has the same size)
};

struct Chart {
  std::string name;      // file stem, "chain-pareto"
  std::string title;
  std::string data;      // the data file's text (gnuplot blocks)
  std::string script;    // the gnuplot script, with @OUT@, @DATA@ and @TERMINAL@ to fill in
  std::vector<std::string> notes;  // what the chart says in words (fitted slopes, front), for the console
  int extraHeight = 0;   // [px] below options.height: the list of points not labelled on the chart
};

// Every chart the rows allow. Rows are sweep records (lab/record.h).
std::vector<Chart> makeCharts(const std::vector<nlohmann::json>& rows, const ChartOptions& options);

// The script with its output, data file and terminal filled in: "png" (pngcairo) or "svg".
std::string chartScript(const Chart& chart, const std::string& terminal, const std::string& output,
                        const std::string& data, const ChartOptions& options);

// The points no other beats in both coordinates (lower is better in both): their indices, by
// increasing x.
std::vector<size_t> paretoFront(const std::vector<std::pair<double, double>>& points);
// The least-squares slope of log y against log x (the order of convergence when x is h).
double logSlope(const std::vector<std::pair<double, double>>& points);

}  // namespace substep::lab
