#include "lab/chart.h"

#include "lab/chart_labels.h"
#include "lab/metrics.h"
#include "lab/method.h"
#include "lab/record.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

namespace substep::lab {

namespace {

using json = nlohmann::json;

const std::vector<std::string> kFamilies = {"a1", "a2", "a3", "a4", "a5", "soft", "bullet", "ode", "mujoco"};

const char* colour(const std::string& family) {
  static const std::map<std::string, const char*> c = {{"a1", "#1f77b4"}, {"a2", "#ff7f0e"}, {"a3", "#2ca02c"},
                                                        {"a4", "#d62728"}, {"a5", "#9467bd"}, {"soft", "#8c564b"},
                                                        {"bullet", "#e377c2"}, {"ode", "#17becf"},
                                                        {"mujoco", "#bcbd22"}};
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
  bool zeroError = false, zeroCost = false;  // drawn at a log axis's floor (the Pareto chart)
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

// A floor for log axes: a zero error (or cost) is drawn there, a tenth of the least other (and
// said so); `none` when there is no other.
double logFloor(const std::vector<Point>& pts, double Point::*field = &Point::error, double none = 1e-12) {
  double lo = INFINITY;
  for (const Point& p : pts)
    if (p.*field > 0) lo = std::min(lo, p.*field);
  return std::isfinite(lo) ? lo / 10 : none;
}

// What a chart that draws zero errors at logFloor() says of it.
std::string zeroText(double floor) {
  char at[32];
  std::snprintf(at, sizeof at, "%.3g", floor);
  return "a zero error is drawn at " + std::string(at) + " (a tenth of the least other)";
}
// ... zero costs (a run quicker than the clock's resolution): on the Pareto chart only.
std::string zeroCostText(double floor) {
  char at[32];
  std::snprintf(at, sizeof at, "%.3g", floor);
  return "a zero cost is drawn at " + std::string(at) + " ms (a tenth of the least other)";
}
// A note in the plot's lower left corner: label 10 the first line, 11 the one above it.
const double kNoteY[] = {0.03, 0.07};
std::string noteLabel(int line, const std::string& text) {
  return "set label " + std::to_string(10 + line) + " '" + text + "' at graph 0.01, graph " + num(kNoteY[line]) + " font ',8'\n";
}
std::string zeroNote(double floor) { return noteLabel(0, zeroText(floor)); }

// The Pareto chart's frame in pixels, fixed so that labels can be placed where gnuplot will draw
// them: the plot area, the ranges it spans (log10) and the list under it.
struct Frame {
  double width = 0, height = 0;            // the whole image [px]
  Box plot;                                // the plot area [px], y downwards
  double lx0 = 0, lx1 = 1, ly0 = 0, ly1 = 1;  // log10 of the axis ranges
  double px(double x) const { return plot.x0 + (std::log10(x) - lx0) / (lx1 - lx0) * (plot.x1 - plot.x0); }
  double py(double y) const { return plot.y1 - (std::log10(y) - ly0) / (ly1 - ly0) * (plot.y1 - plot.y0); }
  std::string screen(double x, double y) const { return "screen " + num(x / width) + ", screen " + num(1 - y / height); }
};

// A log range around [lo, hi] with room for the labels beside the outermost points.
std::pair<double, double> logRange(double lo, double hi, double below, double above) {
  if (!(hi > lo)) lo /= 4, hi *= 4;
  return {std::log10(lo / below), std::log10(hi * above)};
}

// Tics for a log axis over [10^l0, 10^l1]: gnuplot's own are at decades only, one or none on a
// narrow range; then 1, 2 and 5 of each decade.
std::string logTics(const char* axis, double l0, double l1) {
  if (l1 - l0 > 2.5) return "";
  std::string t;
  for (int e = static_cast<int>(std::floor(l0)); e <= static_cast<int>(std::ceil(l1)); ++e)
    for (double m : {1.0, 2.0, 5.0}) {
      const double v = m * std::pow(10.0, e);
      if (std::log10(v) >= l0 && std::log10(v) <= l1) t += (t.empty() ? "" : ", ") + num(v);
    }
  return t.empty() ? "" : std::string("set ") + axis + " (" + t + ")\n";
}

// The frame fixed in screen coordinates and the ranges stated, so that labels land where placed.
std::string frameScript(const Frame& f) {
  return "unset offsets\nset lmargin at screen " + num(f.plot.x0 / f.width) + "\nset rmargin at screen " + num(f.plot.x1 / f.width) +
         "\nset tmargin at screen " + num(1 - f.plot.y0 / f.height) + "\nset bmargin at screen " + num(1 - f.plot.y1 / f.height) +
         "\nset xrange [" + num(std::pow(10, f.lx0)) + ":" + num(std::pow(10, f.lx1)) + "]\nset yrange [" + num(std::pow(10, f.ly0)) +
         ":" + num(std::pow(10, f.ly1)) + "]\n" + logTics("xtics", f.lx0, f.lx1) + logTics("ytics", f.ly0, f.ly1);
}

Chart paretoChart(const std::string& scene, std::vector<Point> pts, const std::string& metric, const std::string& step, bool mixedSteps,
                  const ChartOptions& options) {
  Chart c;
  c.name = scene + "-pareto";
  const double floor = logFloor(pts), costFloor = logFloor(pts, &Point::cost, 1e-3);
  double top = 0;
  bool zero = false, zeroCost = false;
  for (Point& p : pts) {
    if (p.error == 0) {
      p.error = floor;
      p.label += p.label.empty() ? "0" : " (0)";
      zero = p.zeroError = true;
    }
    if (p.cost <= 0) {
      p.cost = costFloor;
      p.label += p.label.empty() ? "cost 0" : " (cost 0)";
      zeroCost = p.zeroCost = true;
    }
    if (std::isfinite(p.error)) top = std::max(top, p.error);
  }
  top = top > 0 ? top * 4 : 1;  // where diverged runs are drawn
  std::vector<const Point*> ok, bad;
  for (const Point& p : pts) {
    if (!std::isfinite(p.cost)) continue;
    if (!p.diverged && std::isfinite(p.error)) ok.push_back(&p);
    if (p.diverged) bad.push_back(&p);
  }
  c.title = scene + ": " + metricLabel(metric) + " against cost (h = " + step + (mixedSteps ? " unless labelled" : "") + ")";
  const std::string x = "cost per simulated second [ms] (median of the repeats)";
  if (ok.empty() && bad.empty()) {
    c.script = header(c.title, x, yLabel(metric)) + "set label 1 'no finite runs' at graph 0.4, graph 0.5\nplot 2 notitle\n";
    c.notes.push_back("Pareto front: none");
    return c;
  }
  // The front: the runs no other beats on both cost and error.
  std::vector<std::pair<double, double>> xy;
  for (const Point* p : ok) xy.emplace_back(p->cost, p->error);
  const std::vector<size_t> front = paretoFront(xy);
  std::set<const Point*> onFront;
  for (size_t i : front) onFront.insert(ok[i]);

  // Who is labelled first: the front by cost, then the others by cost, then the diverged.
  std::vector<const Point*> order;
  for (size_t i : front) order.push_back(ok[i]);
  std::vector<const Point*> rest;
  for (const Point* p : ok)
    if (!onFront.count(p)) rest.push_back(p);
  std::stable_sort(rest.begin(), rest.end(), [](const Point* a, const Point* b) { return a->cost < b->cost; });
  order.insert(order.end(), rest.begin(), rest.end());
  order.insert(order.end(), bad.begin(), bad.end());
  auto textOf = [](const Point* p) { return p->diverged ? p->family + (p->label.empty() ? "" : " " + p->label) : p->label; };

  Frame f;
  f.width = options.width;
  double xlo = INFINITY, xhi = 0, ylo = INFINITY, yhi = bad.empty() ? 0 : top;
  for (const Point* p : order) {
    xlo = std::min(xlo, p->cost), xhi = std::max(xhi, p->cost);
    const double y = p->diverged ? top : p->error;
    ylo = std::min(ylo, y), yhi = std::max(yhi, y);
  }
  std::tie(f.lx0, f.lx1) = logRange(xlo, xhi, 2, 3);
  std::tie(f.ly0, f.ly1) = logRange(ylo, yhi, 2.5, 2.5);
  // The list under the chart is sized by a first placement at the chart's own height; the list
  // only adds height below, so the plot area and every place stay where they were.
  f.height = options.height;
  f.plot = {96, 45, f.width - 200, f.height - 62};  // room for the tick labels and the key
  std::vector<LabelRequest> requests;
  std::vector<Box> obstacles;
  for (const Point* p : order) {
    const double px = f.px(p->cost), py = f.py(p->diverged ? top : p->error);
    requests.push_back({px, py, textOf(p)});
    const double r = onFront.count(p) ? 9 : 6;  // the markers' radii: ps 2.2 open circle, ps 1.4 dot
    obstacles.push_back({px - r, py - r, px + r, py + r});
  }
  // The front's steps (gnuplot's "steps": along at the first y, then up or down at the second x).
  for (size_t k = 0; k + 1 < front.size(); ++k) {
    const double x0 = f.px(xy[front[k]].first), y0 = f.py(xy[front[k]].second);
    const double x1 = f.px(xy[front[k + 1]].first), y1 = f.py(xy[front[k + 1]].second);
    obstacles.push_back({std::min(x0, x1), y0 - 2, std::max(x0, x1), y0 + 2});
    obstacles.push_back({x1 - 2, std::min(y0, y1), x1 + 2, std::max(y0, y1)});
  }
  // The notes in the lower left corner (zeroNote's first line, the cost's above it).
  std::vector<std::string> notes;
  if (zero) notes.push_back(zeroText(floor));
  if (zeroCost) notes.push_back(zeroCostText(costFloor));
  for (size_t k = 0; k < notes.size(); ++k)
    obstacles.push_back(labelBox(notes[k], f.plot.x0 + 0.01 * (f.plot.x1 - f.plot.x0), f.plot.y1 - kNoteY[k] * (f.plot.y1 - f.plot.y0)));
  const std::vector<LabelPlacement> placed = placeLabels(requests, obstacles, f.plot);

  // The list: every point whose label did not fit, with its number (its tag, when that fit) and
  // its coordinates, in columns.
  std::vector<std::string> list;
  for (size_t i = 0; i < order.size(); ++i) {
    if (!placed[i].number) continue;
    const Point* p = order[i];
    // A zero drawn at a floor is listed as 0, not as where it is drawn.
    char at[96];
    std::snprintf(at, sizeof at, "%s%.3g ms, %s", placed[i].kind == LabelPlacement::Kind::Tag ? "" : "(no tag) ", p->zeroCost ? 0.0 : p->cost,
                  p->diverged ? "diverged" : p->zeroError ? "0" : formatMetric(metric, p->error).c_str());
    list.push_back(std::to_string(placed[i].number) + "  " + p->family + (p->label.empty() ? "" : " " + p->label) + ": " + at);
  }
  size_t longest = 0;
  for (const std::string& t : list) longest = std::max(longest, t.size());
  const double columnWidth = kLabelCharWidth * static_cast<double>(longest) + 24;
  const size_t columns = list.empty() ? 1 : std::max<size_t>(1, static_cast<size_t>((f.width - 40) / columnWidth));
  const size_t rows = (list.size() + columns - 1) / columns;
  const double listTop = options.height + 4;
  c.extraHeight = list.empty() ? 0 : static_cast<int>(std::ceil(20 + kLabelHeight * static_cast<double>(rows + 1)));
  f.height = options.height + c.extraHeight;

  std::ostringstream data, plot, labels;
  int index = 0;
  for (const std::string& fam : kFamilies) {
    std::vector<const Point*> mine;
    for (const Point* p : ok)
      if (p->family == fam) mine.push_back(p);
    if (mine.empty()) continue;
    for (const Point* p : mine) data << num(p->cost) << ' ' << num(p->error) << '\n';
    data << "\n\n";
    plot << (index ? ", \\\n     " : "plot ") << "'@DATA@' index " << index << " using 1:2 with points pt 7 ps 1.4 lc rgb '"
         << colour(fam) << "' title " << gpString(fam);
    ++index;
  }
  if (!bad.empty()) {
    for (const Point* p : bad) data << num(p->cost) << ' ' << num(top) << '\n';
    data << "\n\n";
    plot << (index ? ", \\\n     " : "plot ") << "'@DATA@' index " << index
         << " using 1:2 with points pt 2 ps 2 lw 2 lc rgb '#000000' title 'diverged'";
    ++index;
  }
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
  int tag = 100;  // label numbers of their own, clear of the notes' (1, 10)
  for (size_t i = 0; i < order.size(); ++i) {
    if (placed[i].kind == LabelPlacement::Kind::None) continue;
    const std::string text = placed[i].kind == LabelPlacement::Kind::Text ? requests[i].text : std::to_string(placed[i].number);
    labels << "set label " << tag++ << ' ' << gpString(text) << " at " << f.screen(placed[i].x, placed[i].y) << " left font ',8' tc rgb '"
           << (order[i]->diverged ? "#000000" : colour(order[i]->family)) << "' front\n";
  }
  if (!list.empty()) {
    labels << "set label " << tag++ << ' ' << gpString("Not labelled on the chart (number: the tag beside the point; cost per simulated second, " + std::string(metricLabel(metric)) + "):")
           << " at " << f.screen(20, listTop + 10) << " left font ',8'\n";
    for (size_t k = 0; k < list.size(); ++k)
      labels << "set label " << tag++ << ' ' << gpString(list[k]) << " at "
             << f.screen(20 + columnWidth * static_cast<double>(k / rows), listTop + 10 + kLabelHeight * static_cast<double>(1 + k % rows))
             << " left font ',8'\n";
  }
  c.data = data.str();
  const std::string frame = frameScript(f);
  std::string noteLabels;
  for (size_t k = 0; k < notes.size(); ++k) noteLabels += noteLabel(static_cast<int>(k), notes[k]);
  c.script = header(c.title, x, yLabel(metric)) + "set logscale xy\n" + frame + noteLabels + labels.str() + plot.str() + "\n";
  c.notes.push_back("Pareto front: " + (frontText.empty() ? std::string("none") : frontText));
  c.notes.insert(c.notes.end(), notes.begin(), notes.end());
  if (!list.empty()) c.notes.push_back(std::to_string(list.size()) + (list.size() == 1 ? " point" : " points") + " not labelled on the chart, listed under it");
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


// The engine comparison of Erez, Tassa and Todorov (ICRA 2015): error against the real-time factor
// (simulated seconds per wall-clock second), each method a curve over its time steps. Where every
// curve runs over the same time steps the title says which end is which; else each end is
// labelled with its h where the label fits clear of every point, line and other label, and the
// ends that could not be are named in the chart's notes. Made where some method ran at two time
// steps or more.
bool speedChart(const std::string& scene, const std::vector<Point>& pts, const std::string& metric, const ChartOptions& options, Chart& c) {
  std::map<std::string, std::vector<const Point*>> groups;
  std::vector<std::string> order;
  for (const Point& p : pts) {
    if (p.diverged || !std::isfinite(p.error) || !(p.cost > 0)) continue;
    const std::string sig = signature(*p.row, {"dt"});
    if (!groups.count(sig)) order.push_back(sig);
    groups[sig].push_back(&p);
  }
  bool curves = false;
  for (const auto& [sig, g] : groups) curves = curves || g.size() >= 2;
  if (!curves) return false;
  const double floor = logFloor(pts);
  auto rtf = [](const Point* p) { return 1000 / p->cost; };
  auto err = [&](const Point* p) { return p->error > 0 ? p->error : floor; };
  auto hText = [](const Point* p) { return p->row->at("h").get<std::string>(); };

  std::vector<std::string> titles;
  std::set<std::vector<std::string>> stepSets;
  double xlo = INFINITY, xhi = 0, ylo = INFINITY, yhi = 0;
  size_t longest = 0;
  for (const std::string& sig : order) {
    std::vector<const Point*>& g = groups[sig];
    std::sort(g.begin(), g.end(), [](const Point* a, const Point* b) { return a->dt > b->dt; });
    std::string text = g.front()->row->at("method").get<std::string>();
    const size_t h = text.find(":h=");
    if (h != std::string::npos) text.erase(h, text.find(':', h + 1) == std::string::npos ? std::string::npos : text.find(':', h + 1) - h);
    titles.push_back(text);
    longest = std::max(longest, text.size());
    std::vector<std::string> steps;
    for (const Point* p : g) {
      steps.push_back(hText(p));
      xlo = std::min(xlo, rtf(p)), xhi = std::max(xhi, rtf(p)), ylo = std::min(ylo, err(p)), yhi = std::max(yhi, err(p));
    }
    stepSets.insert(steps);
  }
  // The title can say which end is which when every curve has the same steps, its largest h
  // rightmost and its smallest leftmost.
  bool sameSteps = stepSets.size() == 1;
  for (const auto& [sig, g] : groups)
    for (const Point* p : g) sameSteps = sameSteps && rtf(g.front()) >= rtf(p) && rtf(g.back()) <= rtf(p);

  Frame f;
  f.width = options.width;
  f.height = options.height;
  // Room on the right for the key, whose entries are the methods' specs.
  f.plot = {96, 45, f.width - std::max(200.0, 90 + 7.5 * static_cast<double>(longest)), f.height - 62};
  std::tie(f.lx0, f.lx1) = logRange(xlo, xhi, 2, 2);
  std::tie(f.ly0, f.ly1) = logRange(ylo, yhi, 2.5, 2.5);

  // The ends' labels, placed clear of every marker and of the lines between them.
  std::vector<LabelRequest> requests;
  std::vector<const Point*> requested;
  std::vector<Box> obstacles;
  for (const std::string& sig : order) {
    const std::vector<const Point*>& g = groups[sig];
    for (size_t k = 0; k < g.size(); ++k) {
      const double x = f.px(rtf(g[k])), y = f.py(err(g[k]));
      obstacles.push_back({x - 6, y - 6, x + 6, y + 6});
      if (k + 1 < g.size()) {
        const double x1 = f.px(rtf(g[k + 1])), y1 = f.py(err(g[k + 1]));
        const int n = std::max(1, static_cast<int>(std::hypot(x1 - x, y1 - y) / 4));
        for (int i = 1; i < n; ++i) {
          const double t = static_cast<double>(i) / n, sx = x + t * (x1 - x), sy = y + t * (y1 - y);
          obstacles.push_back({sx - 1.5, sy - 1.5, sx + 1.5, sy + 1.5});
        }
      }
      if (!sameSteps && (k == 0 || k + 1 == g.size())) {
        requests.push_back({x, y, hText(g[k])});
        requested.push_back(g[k]);
      }
    }
  }
  std::ostringstream labels;
  std::vector<std::string> unlabelled;
  const std::vector<LabelPlacement> placed = placeLabels(requests, obstacles, f.plot);
  int tag = 100;
  for (size_t i = 0; i < placed.size(); ++i) {
    if (placed[i].kind == LabelPlacement::Kind::Text)
      labels << "set label " << tag++ << ' ' << gpString(requests[i].text) << " at " << f.screen(placed[i].x, placed[i].y)
             << " left font ',8' tc rgb '" << colour(requested[i]->family) << "' front\n";
    else
      unlabelled.push_back(requested[i]->row->at("method").get<std::string>());
  }

  std::ostringstream data, plot;
  std::map<std::string, int> sameFamily;
  for (size_t index = 0; index < order.size(); ++index) {
    const std::vector<const Point*>& g = groups[order[index]];
    for (const Point* p : g) data << num(rtf(p)) << ' ' << num(err(p)) << '\n';
    data << "\n\n";
    // A family's second and later curves (mujoco with RK4 beside its Euler) dashed, other points.
    const int kth = sameFamily[g.front()->family]++;
    static const int kPoints[] = {7, 5, 9, 11, 13};
    plot << (index ? ", \\\n     " : "plot ") << "'@DATA@' index " << index << " using 1:2 with linespoints pt " << kPoints[kth % 5]
         << " ps 1.2 lw 2 dt " << (kth + 1) << " lc rgb '" << colour(g.front()->family) << "' title " << gpString(titles[index]);
    c.notes.push_back(titles[index] + ": " + std::to_string(g.size()) + (g.size() == 1 ? " time step" : " time steps"));
  }
  if (!unlabelled.empty()) {
    std::string t = "h not labelled (no room clear of the curves) at";
    for (size_t k = 0; k < unlabelled.size(); ++k) t += (k ? ", " : " ") + unlabelled[k];
    c.notes.push_back(t);
  }
  const std::vector<std::string>& steps = *stepSets.begin();
  c.name = scene + "-speed";
  c.title = scene + ": " + metricLabel(metric) + " against the real-time factor, " +
            (sameSteps && steps.size() >= 2 ? "h from " + steps.front() + " (right) to " + steps.back() + " (left)" : "each method over h");
  c.data = data.str();
  c.script = header(c.title, "real-time factor (simulated s per wall-clock s, one core; right and low is better)", yLabel(metric)) +
             "set logscale xy\nset key outside right top box opaque font ',9'\n" + frameScript(f) + labels.str() +
             (floor > 0 && std::any_of(pts.begin(), pts.end(), [](const Point& p) { return p.error == 0; }) ? zeroNote(floor) : "") +
             plot.str() + "\n";
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
    charts.push_back(paretoChart(scene, pts, metric, stepText(common), steps.size() > 1, options));
    Chart c;
    if (substepsChart(scene, pts, metric, c)) charts.push_back(c);
    c = Chart{};
    if (havokChart(scene, pts, metric, c)) charts.push_back(c);
    c = Chart{};
    if (convergenceChart(scene, pts, metric, c)) charts.push_back(c);
    c = Chart{};
    if (speedChart(scene, pts, metric, options, c)) charts.push_back(c);
  }
  return charts;
}

std::string chartScript(const Chart& chart, const std::string& terminal, const std::string& output, const std::string& data,
                        const ChartOptions& options) {
  const std::string size = std::to_string(options.width) + "," + std::to_string(options.height + chart.extraHeight);
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
