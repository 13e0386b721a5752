// Charts written to a folder: data and scripts under data/, PNG and SVG drawn by gnuplot, each
// output written under a temporary name and renamed when gnuplot is done (`substep chart` and
// `substep atlas` share this).
#pragma once

#include "lab/chart.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace substep::app {

// gnuplot's path: $SUBSTEP_GNUPLOT, else gnuplot on PATH; "" if neither.
std::string findGnuplot();

// Writes every chart makeCharts() gives for `rows` into `folder`; returns the PNG and SVG paths.
// Prints each chart's notes unless quiet. Throws UsageError when gnuplot is missing or the folder
// cannot be written, std::runtime_error when gnuplot fails.
std::vector<std::string> writeCharts(const std::vector<nlohmann::json>& rows, const lab::ChartOptions& options,
                                     const std::string& folder, bool quiet);

}  // namespace substep::app
