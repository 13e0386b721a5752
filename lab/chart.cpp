#include "lab/chart.h"

#include "lab/metrics.h"
#include "lab/method.h"
#include "lab/record.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>

namespace substep::lab {

namespace {

using json = nlohmann::json;

const std::vector<std::string> kFamilies = {"a1", "a2", "a3", "a4", "a5", "soft", "bullet"};

const char* colour(const std::string& family) {
  static const std::map<std::string, const char*> c = {{"a1", "#1f77b4"}, {"a2", "#ff7f0e"}, {"a3", "#2ca02c"},
                                                        {"a4", "#d62728"}, {"a5", "#9467bd"}, {"soft", "#8c564b"},
                                                        {"bullet", "#e377c2"}};
  const auto it = c.find(family);
  return it == c.end() ? "#7f7f7f" : it->second;
}

// gnuplot's double-quoted strings: backslashes and quotes escaped.
std::string gpString(const std::string& s) {
  std::string q = "\"";
  for (char ch : s) {
    if (ch == '"' || ch == '\\') q += '\\';
    q += ch;
  }
  return q + "\"";
}

std::string num(double x) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", x);
  return buf;
}

// One record as a chart sees it.
struct Point {
  const json* row = nullptr;
  std::string family, label;
  double cost = NAN;    // ms per simulated second
  double error = NAN;
  double dt = NAN;
  int n = 1, m = 1;
  bool diverged = false;
};

std::string metricOf(const json& row, const ChartOptions& o) {
  return o.error.empty() ? row["error"]["metric"].get<std::string>() : o.error;
}

// The method as a point's label: its settings without the family ("n=4 m=1"), with h when it is
// not the chart's common time step and the method does not name it.
std::string labelOf(const json& row, double commonStep) {
  std::string text = row["method"].get<std::string>();
  const size_t colon = text.find(':');
  std::string label = colon == std::string::npos ? "" : text.substr(colon + 1);
  std::replace(label.begin(), label.end(), ':', ' ');
  if (label.rfind("preset=", 0) == 0) label = label.substr(7);  // "4-medium"
  if (row["settings"]["dt"].get<double>() != commonStep && text.find("h=") == std::string::npos)
    label += (label.empty() ? "" : " ") + std::string("h=") + row["h"].get<std::string>();
  return label;
}

// Settings that tell two records of a family apart, except those a chart varies.
std::string signature(const json& row, const std::set<std::string>& varied) {
  std::string s = row["family"].get<std::string>();
  for (const auto& [k, v] : row["settings"].items())
    if (!varied.count(k)) s += "|" + k + "=" + v.dump();
  return s;
}

std::string yLabel(const std::string& metric) {
  const std::string unit = metricUnit(metric);
  return std::string(metricLabel(metric)) + (unit.empty() ? " (share)" : " [" + unit + "]");
}

std::string header(const std::string& title, const std::string& x, const std::string& y) {
  return "@TERMINAL@\nset output '@OUT@'\nset termoption noenhanced\nset title " + gpString(title) + "\nset xlabel " +
         gpString(x) + "\nset ylabel " + gpString(y) + "\nset grid xtics ytics mxtics mytics lc rgb '#dddddd'\n"
         "set key outside right top box opaque\nset border lw 1.2\nset offsets graph 0.05, graph 0.2, graph 0.15, graph 0.1\n"
         "set format x '%g'\nset format y '%g'\n";
}

// A floor for log axes: a zero error is drawn there (and said so).
double logFloor(const std::vector<Point>& pts) {
  double lo = INFINITY;
  for (const Point& p : pts)
    if (p.error > 0) lo = std::min(lo, p.error);
  return std::isfinite(lo) ? lo / 10 : 1e-12;
}

// Said on a chart that draws zero errors at logFloor().
std::string zeroNote(double floor) {
  char at[32];
  std::snprintf(at, sizeof at, "%.3g", floor);
  return "set label 10 'a zero error is drawn at " + std::string(at) + " (a tenth of the least other)' at graph 0.01, "
         "graph 0.03 font ',8'\n";
}

Chart paretoChart(const std::string& scene, std::vector<Point> pts, const std::string& metric, const std::string& step, bool mixedSteps) {
  Chart c;
  c.name = scene + "-pareto";
  const double floor = logFloor(pts);
  double top = 0;
  for (Point& p : pts) {
    if (p.error == 0) {
      p.error = floor;
      p.label += p.label.empty() ? "0" : " (0)";
    }
    if (std::isfinite(p.error)) top = std::max(top, p.error);
  }
  top = top > 0 ? top * 4 : 1;
  std::ostringstream data, plot;
  int index = 0;
  bool zero = false;
  for (const std::string& fam : kFamilies) {
    std::vector<const Point*> mine;
    for (const Point& p : pts)
      if (p.family == fam && !p.diverged && std::isfinite(p.error) && std::isfinite(p.cost)) mine.push_back(&p);
    if (mine.empty()) continue;
    for (const Point* p : mine) {
      data << num(p->cost) << ' ' << num(p->error) << ' ' << gpString(p->label) << '\n';
      zero = zero || p->error == floor;
    }
    data << "\n\n";
    plot << (index ? ", \\\n     " : "plot ") << "'@DATA@' index " << index << " using 1:2 with points pt 7 ps 1.4 lc rgb '"
         << colour(fam) << "' title " << gpString(fam) << ", \\\n     '' index " << index
         << " using 1:2:3 with labels offset char 0.6,0.6 left font ',8' tc rgb '" << colour(fam) << "' notitle";
    ++index;
  }
  std::vector<const Point*> bad;
  for (const Point& p : pts)
    if (p.diverged && std::isfinite(p.cost)) bad.push_back(&p);
  if (!bad.empty()) {
    for (const Point* p : bad) data << num(p->cost) << ' ' << num(top) << ' ' << gpString(p->family + " " + p->label) << '\n';
    data << "\n\n";
    plot << (index ? ", \\\n     " : "plot ") << "'@DATA@' index " << index
         << " using 1:2 with points pt 2 ps 2 lw 2 lc rgb '#000000' title 'diverged', \\\n     '' index " << index
         << " using 1:2:3 with labels offset char 0.6,-0.8 left font ',8' notitle";
    ++index;
  }
  // The front: the runs no other beats on both cost and error.
  std::vector<std::pair<double, double>> xy;
  std::vector<const Point*> ok;
  for (const Point& p : pts)
    if (!p.diverged && std::isfinite(p.error) && std::isfinite(p.cost)) {
      xy.emplace_back(p.cost, p.error);
      ok.push_back(&p);
    }
  const std::vector<size_t> front = paretoFront(xy);
  std::string frontText;
  for (size_t i : front) {
    data << num(xy[i].first) << ' ' << num(xy[i].second) << '\n';
    frontText += (frontText.empty() ? "" : ", ") + ok[i]->family + (ok[i]->label.empty() ? "" : " " + ok[i]->label);
  }
  if (!front.empty()) {
    data << "\n\n";
    plot << (index ? ", \\\n     " : "plot ") << "'@DATA@' index " << index
         << " using 1:2 with steps lw 2 dt 2 lc rgb '#333333' title 'Pareto front', \\\n     '' index " << index
         << " using 1:2 with points pt 6 ps 2.2 lw 1.5 lc rgb '#333333' notitle";
    ++index;
  }
  c.title = scene + ": " + metricLabel(metric) + " against cost (h = " + step + (mixedSteps ? " unless labelled" : "") + ")";
  c.data = data.str();
  std::string x = "cost per simulated second [ms] (median of the repeats)";
  c.script = header(c.title, x, yLabel(metric)) + "set logscale xy\n" +
             (zero ? zeroNote(floor) : "") +
             (plot.str().empty() ? "set label 1 'no finite runs' at graph 0.4, graph 0.5\nplot 2 notitle\n" : plot.str() + "\n");
  c.notes.push_back("Pareto front: " + (frontText.empty() ? std::string("none") : frontText));
  return c;
}

// "Sub-steps beat micro-iterations at equal work": for each k, a2 with k iterations against a
// sub-stepping method with k sub-steps of one iteration, at one time step.
bool substepsChart(const std::string& scene, const std::vector<Point>& pts, const std::string& metric, Chart& c) {
  std::map<std::string, std::vector<const Point*>> groups;  // signature -> points
  for (const Point& p : pts) {
    if (p.diverged || !std::isfinite(p.error)) continue;
    if (p.family == "a2") groups[signature(*p.row, {"iterations"})].push_back(&p);
    if ((p.family == "a3" || p.family == "a4" || p.family == "a5" || p.family == "soft") && p.m == 1)
      groups[signature(*p.row, {"substeps"})].push_back(&p);
  }
  // Per family, the group with the most distinct k.
  std::map<std::string, std::vector<const Point*>> best;
  for (const auto& [sig, g] : groups) {
    const std::string fam = g.front()->family;
    if (g.size() > best[fam].size()) best[fam] = g;
  }
  if (best["a2"].size() < 2) return false;
  int others = 0;
  for (const auto& [fam, g] : best) others += fam != "a2" && g.size() >= 2;
  if (!others) return false;
  c.name = scene + "-substeps";
  c.title = scene + ": n sub-steps of 1 iteration against 1 step of n iterations (equal solver work)";
  std::ostringstream data, plot;
  int index = 0;
  const double floor = logFloor(pts);
  bool zero = false;
  for (const auto& [fam, g] : best) {
    if (g.size() < 2) continue;
    std::vector<std::pair<int, double>> kv;
    for (const Point* p : g) {
      kv.emplace_back(fam == "a2" ? p->m : p->n, p->error > 0 ? p->error : floor);
      zero = zero || !(p->error > 0);
    }
    std::sort(kv.begin(), kv.end());
    for (const auto& [k, e] : kv) data << k << ' ' << num(e) << '\n';
    data << "\n\n";
    const std::string title = fam == "a2" ? "a2: 1 step of n iterations" : fam + ": n sub-steps of 1 iteration";
    plot << (index ? ", \\\n     " : "plot ") << "'@DATA@' index " << index << " using 1:2 with linespoints pt 7 ps 1.3 lw 2 lc rgb '"
         << colour(fam) << "' title " << gpString(title);
    ++index;
    std::string note = title + ":";
    for (const auto& [k, e] : kv) note += " n=" + std::to_string(k) + " " + formatMetric(metric, e);
    c.notes.push_back(note);
  }
  c.data = data.str();
  c.script = header(c.title, "solver sweeps per step n", yLabel(metric)) + "set logscale xy\nset logscale x 2\n" +
             (zero ? zeroNote(floor) : "") + plot.str() + "\n";
  return true;
}

// A3 against A4 against A5: error and cost per step against n, the other settings equal.
bool havokChart(const std::string& scene, const std::vector<Point>& pts, const std::string& metric, Chart& c) {
  std::map<std::string, std::vector<const Point*>> best;
  std::map<std::string, std::map<std::string, std::vector<const Point*>>> groups;
  for (const Point& p : pts)
    if ((p.family == "a3" || p.family == "a4" || p.family == "a5") && !p.diverged && std::isfinite(p.error))
      groups[p.family][signature(*p.row, {"substeps", "algorithm", "block_solve"})].push_back(&p);
  int families = 0;
  bool line = false;  // against n: some family over two n or more
  for (auto& [fam, gs] : groups) {
    for (auto& [sig, g] : gs)
      if (g.size() > best[fam].size()) best[fam] = g;
    families += !best[fam].empty();
    std::set<int> ns;
    for (const Point* p : best[fam]) ns.insert(p->n);
    line = line || ns.size() >= 2;
  }
  if (families < 2 || !line) return false;
  c.name = scene + "-havok";
  c.title = scene + ": A3 (conceptual), A4 (approximative) and A5 (actual) against n";
  std::ostringstream data, errPlot, costPlot;
  int index = 0;
  const double floor = logFloor(pts);
  bool zero = false;
  for (const auto& [fam, g] : best) {
    if (g.empty()) continue;
    std::vector<const Point*> s = g;
    std::sort(s.begin(), s.end(), [](const Point* a, const Point* b) { return a->n < b->n; });
    std::string note = fam + ":";
    for (const Point* p : s) {
      zero = zero || !(p->error > 0);
      const double msPerStep = p->cost * p->dt;
      data << p->n << ' ' << num(p->error > 0 ? p->error : floor) << ' ' << num(msPerStep) << '\n';
      char buf[64];
      std::snprintf(buf, sizeof buf, ", %.4g ms/step", msPerStep);
      note += " n=" + std::to_string(p->n) + " " + formatMetric(metric, p->error) + buf;
    }
    data << "\n\n";
    for (std::ostringstream* plot : {&errPlot, &costPlot})
      *plot << (index ? ", \\\n     " : "plot ") << "'@DATA@' index " << index << " using 1:" << (plot == &errPlot ? 2 : 3)
            << " with linespoints pt 7 ps 1.3 lw 2 lc rgb '" << colour(fam) << "' title " << gpString(fam);
    ++index;
    c.notes.push_back(note);
  }
  c.data = data.str();
  c.script = "@TERMINAL@\nset output '@OUT@'\nset termoption noenhanced\nset multiplot layout 1,2 title " + gpString(c.title) +
             "\nset grid lc rgb '#dddddd'\nset key top right box opaque\nset logscale x 2\nset xlabel 'sub-steps n'\n"
             "set format x '%g'\nset format y '%g'\n"
             "set logscale y\nset title 'error'\nset ylabel " + gpString(yLabel(metric)) + "\n" + (zero ? zeroNote(floor) : "") +
             errPlot.str() + "\nunset label 10" +
             "\nset title 'cost'\nset ylabel 'cost per step [ms]'\nunset logscale y\nset yrange [0:*]\n" + costPlot.str() +
             "\nunset multiplot\n";
  return true;
}

// Error against h, per method (settings but h equal), with the fitted order.
bool convergenceChart(const std::string& scene, const std::vector<Point>& pts, const std::string& metric, Chart& c) {
  std::map<std::string, std::vector<const Point*>> groups;
  for (const Point& p : pts)
    if (!p.diverged && p.error > 0 && std::isfinite(p.error)) groups[signature(*p.row, {"dt"})].push_back(&p);
  std::ostringstream data, plot;
  int index = 0;
  for (auto& [sig, g] : groups) {
    std::set<double> steps;
    for (const Point* p : g) steps.insert(p->dt);
    if (steps.size() < 2) continue;
    std::sort(g.begin(), g.end(), [](const Point* a, const Point* b) { return a->dt < b->dt; });
    std::vector<std::pair<double, double>> xy;
    for (const Point* p : g) {
      xy.emplace_back(p->dt, p->error);
      data << num(p->dt) << ' ' << num(p->error) << '\n';
    }
    data << "\n\n";
    const double slope = logSlope(xy);
    std::string label = g.front()->family;
    std::string text = g.front()->row->at("method").get<std::string>();
    const size_t h = text.find(":h=");
    if (h != std::string::npos) text.erase(h, text.find(':', h + 1) == std::string::npos ? std::string::npos : text.find(':', h + 1) - h);
    char buf[64];
    std::snprintf(buf, sizeof buf, " (slope %.2f)", slope);
    label = text + buf;
    plot << (index ? ", \\\n     " : "plot ") << "'@DATA@' index " << index << " using 1:2 with linespoints pt 7 ps 1.3 lw 2 lc rgb '"
         << colour(g.front()->family) << "' title " << gpString(label);
    c.notes.push_back(label);
    ++index;
  }
  if (!index) return false;
  c.name = scene + "-convergence";
  c.title = scene + ": " + metricLabel(metric) + " against the time step (fitted order in the legend)";
  c.data = data.str();
  c.script = header(c.title, "time step h [s]", yLabel(metric)) + "set logscale xy\n" + plot.str() + "\n";
  return true;
}

}  // namespace

std::vector<size_t> paretoFront(const std::vector<std::pair<double, double>>& points) {
  std::vector<size_t> order(points.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return points[a].first != points[b].first ? points[a].first < points[b].first : points[a].second < points[b].second;
  });
  std::vector<size_t> front;
  double best = INFINITY;
  for (size_t i : order)
    if (points[i].second < best) {
      best = points[i].second;
      front.push_back(i);
    }
  return front;
}

double logSlope(const std::vector<std::pair<double, double>>& points) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int n = 0;
  for (const auto& [x, y] : points) {
    if (!(x > 0 && y > 0)) continue;
    const double lx = std::log(x), ly = std::log(y);
    sx += lx, sy += ly, sxx += lx * lx, sxy += lx * ly;
    ++n;
  }
  const double d = n * sxx - sx * sx;
  return n >= 2 && d != 0 ? (n * sxy - sx * sy) / d : NAN;
}

std::vector<Chart> makeCharts(const std::vector<json>& rows, const ChartOptions& options) {
  std::map<std::string, std::vector<Point>> byScene;
  std::vector<std::string> order;
  for (const json& r : rows) {
    if (r.value("refused", false)) continue;
    const std::string scene = r["scene"].get<std::string>();
    if (!byScene.count(scene)) order.push_back(scene);
    Point p;
    p.row = &r;
    p.family = r["family"].get<std::string>();
    p.cost = r["cost"]["ms_per_second"].is_number() ? r["cost"]["ms_per_second"].get<double>() : NAN;
    const std::optional<double> e = recordValue(r, metricOf(r, options));
    p.error = e ? *e : NAN;
    p.dt = r["settings"]["dt"].get<double>();
    p.n = r["settings"].value("substeps", 1.0);
    p.m = r["settings"].value("iterations", 1.0);
    p.diverged = r.value("diverged", false) || !r.value("finite", true);
    byScene[scene].push_back(p);
  }
  std::vector<Chart> charts;
  for (const std::string& scene : order) {
    std::vector<Point>& pts = byScene[scene];
    // The time step most runs have: the title states it, labels the others.
    std::map<double, int> steps;
    for (const Point& p : pts) ++steps[p.dt];
    const double common = std::max_element(steps.begin(), steps.end(), [](const auto& a, const auto& b) {
                            return a.second < b.second;
                          })->first;
    for (Point& p : pts) p.label = labelOf(*p.row, common);
    const std::string metric = metricOf(*pts.front().row, options);
    charts.push_back(paretoChart(scene, pts, metric, stepText(common), steps.size() > 1));
    Chart c;
    if (substepsChart(scene, pts, metric, c)) charts.push_back(c);
    c = Chart{};
    if (havokChart(scene, pts, metric, c)) charts.push_back(c);
    c = Chart{};
    if (convergenceChart(scene, pts, metric, c)) charts.push_back(c);
  }
  return charts;
}

std::string chartScript(const Chart& chart, const std::string& terminal, const std::string& output, const std::string& data,
                        const ChartOptions& options) {
  const std::string size = std::to_string(options.width) + "," + std::to_string(options.height);
  const std::string term = terminal == "svg" ? "set terminal svg size " + size + " dynamic font 'DejaVu Sans,11' background '#ffffff'"
                                             : "set terminal pngcairo size " + size + " font 'DejaVu Sans,11' background '#ffffff'";
  std::string s = chart.script;
  auto fill = [&](const std::string& what, const std::string& with) {
    for (size_t at = s.find(what); at != std::string::npos; at = s.find(what, at + with.size())) s.replace(at, what.size(), with);
  };
  // Single-quoted in the script: a quote in a path is doubled, gnuplot's escape there.
  auto single = [](std::string p) {
    for (size_t at = p.find('\''); at != std::string::npos; at = p.find('\'', at + 2)) p.insert(at, 1, '\'');
    return p;
  };
  fill("@TERMINAL@", term);
  fill("@OUT@", single(output));
  fill("@DATA@", single(data));
  return s;
}

}  // namespace substep::lab
