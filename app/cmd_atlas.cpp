// substep atlas: every atlas scene (assets/scenes/atlas/) under every method of a set, judged by
// the scene's criteria; writes DIR/index.html (scene x method, pass/fail with the figure, each
// cell linking a side-by-side clip), DIR/atlas.json, DIR/atlas.jsonl (one record per cell, as a
// sweep writes them), DIR/atlas.md (the table for docs/lab.md), the clips and the charts.
#include "app/chart_files.h"
#include "app/commands.h"
#include "app/common.h"
#include "lab/atlas.h"
#include "lab/provenance.h"
#include "lab/record.h"
#include "render/frame_sink.h"
#include "render/session.h"
#include "render/video.h"

#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

#ifndef SUBSTEP_SOURCE_DIR
#define SUBSTEP_SOURCE_DIR "."
#endif

namespace substep::app {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct AtlasOptions {
  std::string output;
  std::vector<std::string> scenes;
  std::string methods = lab::defaultAtlasMethods();
  bool noClips = false;
  double clipSeconds = 2;
  int fps = 30;
  std::string size = "960x540";
  std::string expected, writeExpected;
  int repeat = 1;
  std::string record;  // a folder for a recording of every cell's run, "" for none
  bool quiet = false;
};

struct SceneResult {
  Scene scene;
  std::vector<lab::AtlasCell> cells;
  std::vector<std::string> clips;  // per cell: the clip's file name in clips/, "" if none
  std::vector<int> panels;         // per cell: its panel in the clip (1-based)
  std::string chart;               // charts/<scene>-pareto.png, "" if none
  std::string error;               // the quantity the scene calls error
};

std::string html(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string fixed(double x, int digits) {
  std::ostringstream o;
  o << std::fixed << std::setprecision(digits) << x;
  return o.str();
}

// The criteria in words: "max displacement <= 10.0 cm; the sliding bodies move >= 30 cm".
std::string criteriaText(const Scene& s) {
  if (!s.criteria) return "no criteria";
  const SceneCriteria& c = *s.criteria;
  std::string t;
  auto add = [&](const std::string& x) { t += (t.empty() ? "" : "; ") + x; };
  add("finite, no divergence");
  for (const auto& [name, bound] : c.pass) add(std::string(lab::metricLabel(name)) + " <= " + lab::formatMetric(name, bound));
  if (c.moving) add("the sliding bodies move >= " + lab::formatLength(c.moving->atLeast));
  if (c.stayIn) add(s.model.bodies[static_cast<size_t>(c.stayIn->body)].name + " stays on its side");
  if (c.turns) add(s.model.bodies[static_cast<size_t>(c.turns->body)].name + "'s axis turns >= " +
                   fixed(c.turns->atLeast * 180 / M_PI, 0) + " deg (it flips)");
  return t + " (" + numberText(c.seconds) + " s)";
}

std::string errorText(const SceneResult& r, const lab::AtlasCell& c) {
  if (c.run.refused) return "";
  const std::optional<double> v = lab::metricValue(c.run.metrics, r.error);
  return v ? std::string(lab::metricLabel(r.error)) + " " + lab::formatMetric(r.error, *v) : "";
}

// --- the clips --------------------------------------------------------------------------------

// One panel per cell; the panels are never stepped: the states each run kept (the peers' too) are drawn.
render::RenderSession clipSession(const SceneResult& r, const std::vector<size_t>& cells) {
  using namespace render;
  auto scene = std::make_shared<const Scene>(r.scene);
  std::vector<PanelSetup> setups;
  for (size_t i : cells) {
    const lab::RunResult& run = r.cells[i].run;
    SolverSettings s = run.settings;
    if (run.method.isPeer()) s = resolve(SolverOverrides{});  // a panel needs substep settings; they are never used
    setups.push_back({s, run.method.text});
  }
  Look look;
  look.camera = chooseCamera(*scene, CameraOptions{});
  return RenderSession(scene, setups, look);
}

// The state a cell's run kept for frame k; its last one after the run ended.
const State& clipState(const SceneResult& r, const lab::AtlasCell& c, long long k) {
  const std::vector<State>& f = c.run.frames;
  return f.empty() ? r.scene.initial : f[std::min(static_cast<size_t>(k), f.size() - 1)];
}

// The panel's label: the method and its verdict, in the verdict's colour.
void labelPanel(render::DrawList& dl, const lab::AtlasCell& c) {
  std::string verdict = lab::resultName(c.verdict.result);
  for (char& ch : verdict) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  dl.label = c.run.method.text + "  " + verdict;
  dl.labelColour = c.verdict.result == lab::Verdict::Result::Pass   ? render::Vec4f(0.55f, 1.0f, 0.55f, 1)
                   : c.verdict.result == lab::Verdict::Result::Fail ? render::Vec4f(1.0f, 0.55f, 0.5f, 1)
                                                                    : render::Vec4f(0.8f, 0.8f, 0.8f, 1);
}

// A clip of up to four cells side by side.
void writeClip(const SceneResult& r, const std::vector<size_t>& cells, const std::string& path, const AtlasOptions& o,
               render::GlRenderer& renderer, const std::string& ffmpeg) {
  using namespace render;
  RenderSession session = clipSession(r, cells);
  VideoOptions vo;
  vo.fps = o.fps;
  vo.crf = 23;
  VideoSink sink(ffmpeg, path, renderer.width(), renderer.height(), vo);
  const long long frames = std::max(1LL, std::llround(std::min(o.clipSeconds, r.scene.criteria ? r.scene.criteria->seconds : 3.0) * o.fps));
  Image img;
  for (long long k = 0; k < frames; ++k) {
    if (InterruptGuard::interrupted()) throw Interrupted();
    std::vector<DrawList> lists;
    for (size_t p = 0; p < cells.size(); ++p) {
      const lab::AtlasCell& c = r.cells[cells[p]];
      DrawList dl = session.drawList(static_cast<int>(p), &clipState(r, c, k));
      labelPanel(dl, c);
      lists.push_back(std::move(dl));
    }
    renderer.render(gridViews(lists, renderer.width(), renderer.height()), img);
    sink.write(img);
  }
  sink.commit();
}

// The scene's clips, four cells to a clip, and each cell's clip and panel in it.
void writeSceneClips(SceneResult& r, const fs::path& dir, const AtlasOptions& o, render::GlRenderer& renderer,
                     const std::string& ffmpeg) {
  const std::string name = lab::sceneName(r.scene);
  for (size_t g = 0; g * 4 < r.cells.size(); ++g) {
    std::vector<size_t> group;
    for (size_t i = g * 4; i < std::min(r.cells.size(), g * 4 + 4); ++i) group.push_back(i);
    const std::string file = name + "-" + std::to_string(g + 1) + ".mp4";
    writeClip(r, group, (dir / "clips" / file).string(), o, renderer, ffmpeg);
    for (size_t p = 0; p < group.size(); ++p) {
      r.clips[group[p]] = file;
      r.panels[group[p]] = static_cast<int>(p + 1);
    }
  }
}

// --- the page ---------------------------------------------------------------------------------

std::string cellClass(lab::Verdict::Result r) {
  switch (r) {
    case lab::Verdict::Result::Pass: return "pass";
    case lab::Verdict::Result::Fail: return "fail";
    default: return "refused";
  }
}

void writePageHead(std::ostream& h, const json& meta) {
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>substep failure atlas</title>\n<style>\n"
       "body{font-family:DejaVu Sans,Arial,sans-serif;margin:1.5em;color:#222}table{border-collapse:collapse;font-size:12px}\n"
       "th,td{border:1px solid #999;padding:4px 6px;vertical-align:top}th{background:#eee}td.scene{max-width:22em}\n"
       "td.pass{background:#c9f0c4}td.fail{background:#f6c6c2}td.refused{background:#ddd;color:#555}\n"
       "td.changed{outline:3px solid #f39c12;outline-offset:-3px}.v{font-weight:bold}.small{font-size:11px;color:#444}\n"
       "a{color:#1a4f9c}img{max-width:960px;border:1px solid #ccc;margin:6px 0}\n</style></head><body>\n";
  h << "<h1>The failure atlas</h1>\n<p>Each scene of <code>assets/scenes/atlas/</code> under each method, judged by the "
       "scene's own criteria (its <code>criteria</code> block). Green: pass; red: fail; grey: the method cannot run the "
       "scene. Each cell gives the check that decided, the scene's error measure and the cost per step, and links a clip of "
       "the method beside three others. See <code>docs/lab.md</code>.</p>\n";
  h << "<p class=\"small\">commit " << html(meta["commit"].get<std::string>()) << ", " << html(meta["date_utc"].get<std::string>())
    << ", " << html(meta["cpu"].get<std::string>()) << "; physics runs " << fixed(meta["physics_seconds"].get<double>(), 1)
    << " s, clips " << fixed(meta["clip_seconds"].get<double>(), 1) << " s, charts " << fixed(meta["chart_seconds"].get<double>(), 1)
    << " s (wall).</p>\n";
}

// The verdict the expected table gives the cell when it differs from `result`, else "".
std::string expectedOtherwise(const lab::VerdictTable* expected, const std::string& scene, const std::string& method,
                              const std::string& result) {
  if (!expected) return "";
  const auto row = expected->find(scene);
  if (row == expected->end()) return "";
  const auto cell = row->second.find(method);
  return cell != row->second.end() && cell->second != result ? cell->second : "";
}

void writeCellHtml(std::ostream& h, const SceneResult& r, size_t i, const std::string& was) {
  const lab::AtlasCell& c = r.cells[i];
  h << "<td class=\"" << cellClass(c.verdict.result) << (was.empty() ? "" : " changed") << "\"><span class=\"v\">"
    << lab::resultName(c.verdict.result) << "</span>" << (was.empty() ? "" : " <span class=\"small\">(expected " + was + ")</span>")
    << "<br>" << html(c.verdict.figure);
  const std::string err = errorText(r, c);
  if (!err.empty() && c.verdict.figure.find(lab::metricLabel(r.error)) == std::string::npos) h << "<br>" << html(err);
  if (!c.run.refused) h << "<br><span class=\"small\">" << fixed(c.run.cost.msPerStep, 3) << " ms/step</span>";
  if (!r.clips[i].empty())
    h << "<br><a href=\"clips/" << html(r.clips[i]) << "\">clip</a> <span class=\"small\">(panel " << r.panels[i] << ")</span>";
  // With recordings (--record): "inspect" opens the scene's recordings side by side in the viewer,
  // this cell's panel at its first failure; the page's script keeps it only where a server serves
  // the atlas (substep serve --lab), since a file has no viewer behind it.
  std::vector<std::string> recs;
  int panel = -1;
  for (size_t k = 0; k < r.cells.size(); ++k)
    if (!r.cells[k].run.recording.empty() && recs.size() < 4) {
      if (k == i) panel = static_cast<int>(recs.size());
      recs.push_back(r.cells[k].run.recording);
    }
  if (panel < 0 && !c.run.recording.empty()) {  // beyond the first four: this one and the three before it
    recs.assign({c.run.recording});
    panel = 0;
  }
  if (panel >= 0) {
    std::string list;
    for (const std::string& x : recs) list += (list.empty() ? "" : ",") + x;
    h << " <a class=\"inspect\" hidden data-recordings=\"" << html(list) << "\" data-panel=\"" << panel
      << "\" href=\"#\">inspect</a>";
  }
  h << "</td>";
}

// A scene's row of the table; returns how many of its verdicts differ from the expected table.
int writeSceneRowHtml(std::ostream& h, const SceneResult& r, const lab::VerdictTable* expected) {
  const std::string name = lab::sceneName(r.scene);
  h << "<tr><td class=\"scene\"><b><a href=\"#" << html(name) << "\">" << html(name) << "</a></b><br><span class=\"small\">"
    << html(r.scene.criteria ? r.scene.criteria->stresses : r.scene.description) << "<br><i>pass: " << html(criteriaText(r.scene))
    << "</i></span></td>";
  int changed = 0;
  for (size_t i = 0; i < r.cells.size(); ++i) {
    const lab::AtlasCell& c = r.cells[i];
    const std::string was = expectedOtherwise(expected, name, c.run.method.text, lab::resultName(c.verdict.result));
    changed += !was.empty();
    writeCellHtml(h, r, i, was);
  }
  h << "</tr>\n";
  return changed;
}

void writeChartsHtml(std::ostream& h, const std::vector<SceneResult>& results) {
  h << "<h2>Charts: error against cost</h2>\n<p>Per scene, each method a point (its family's colour), the Pareto front "
       "dashed: the runs no other beats in both cost and error. Diverged runs are crosses at the top.</p>\n";
  for (const SceneResult& r : results) {
    const std::string name = lab::sceneName(r.scene);
    h << "<h3 id=\"" << html(name) << "\">" << html(name) << "</h3>\n<p class=\"small\">" << html(r.scene.description) << "</p>\n";
    if (!r.chart.empty()) h << "<img src=\"" << html(r.chart) << "\" alt=\"" << html(name) << ": error against cost\">\n";
  }
}

// Written under a temporary name and renamed over `path`.
void writeText(const std::string& path, const std::string& text) {
  AtomicFile f(path);
  f.out() << text;
  f.commit();
}

void writePage(const std::vector<SceneResult>& results, const std::vector<lab::Method>& methods, const json& meta,
               const lab::VerdictTable* expected, const std::string& path) {
  std::ostringstream h;
  writePageHead(h, meta);
  h << "<table>\n<tr><th>scene: what it stresses; pass criteria</th>";
  for (const lab::Method& m : methods) h << "<th>" << html(m.text) << "</th>";
  h << "</tr>\n";
  int changed = 0;
  for (const SceneResult& r : results) changed += writeSceneRowHtml(h, r, expected);
  h << "</table>\n";
  if (expected)
    h << "<p>" << (changed ? std::to_string(changed) + " verdicts differ from" : "Every verdict agrees with")
      << " the expected table (<code>tests/data/atlas_expected.json</code>)" << (changed ? ": outlined in orange." : ".") << "</p>\n";
  writeChartsHtml(h, results);
  // "inspect" links: to the viewer of the server that serves this page under /lab/ (docs/server.md).
  h << "<script>\n"
       "if (location.protocol.startsWith('http') && location.pathname.startsWith('/lab/')) {\n"
       "  const dir = location.pathname.slice(5).replace(/[^/]*$/, '');\n"
       "  for (const a of document.querySelectorAll('a.inspect')) {\n"
       "    const recs = a.dataset.recordings.split(',').map(r => encodeURIComponent(dir + r)).join(',');\n"
       "    a.href = '/?recordings=' + recs + '&focus=' + a.dataset.panel;\n"
       "    a.hidden = false;\n"
       "  }\n"
       "}\n</script>\n";
  h << "</body></html>\n";
  writeText(path, h.str());
}

std::string markdownTable(const std::vector<SceneResult>& results, const std::vector<lab::Method>& methods) {
  std::ostringstream m;
  m << "| scene |";
  for (const lab::Method& x : methods) m << " " << x.text << " |";
  m << "\n|---|";
  for (size_t i = 0; i < methods.size(); ++i) m << "---|";
  m << "\n";
  for (const SceneResult& r : results) {
    m << "| " << lab::sceneName(r.scene) << " |";
    for (const lab::AtlasCell& c : r.cells) {
      std::string fig = c.verdict.figure;
      if (c.run.refused && !c.run.method.isPeer() && c.run.settings.algorithm == Algorithm::A1)
        fig = "too large for a1's dense MLCP";  // the refusal in full is on the page
      for (char& ch : fig)
        if (ch == '|') ch = '/';
      m << " **" << lab::resultName(c.verdict.result) << "** " << fig << " |";
    }
    m << "\n";
  }
  return m.str();
}

// --- the plan: everything given checked before the first run ----------------------------------

struct AtlasPlan {
  std::vector<lab::Method> methods;
  std::vector<SceneResult> results;  // a scene each, in order; the runs fill in the rest
  int width = 0, height = 0;         // of the clips
  std::unique_ptr<lab::VerdictTable> expected;
  std::string ffmpeg;                // "" with --no-clips
  fs::path dir;
};

// Wall times [s].
struct AtlasTimes {
  double physics = 0, clips = 0, charts = 0;
};

std::vector<lab::Method> atlasMethods(const std::string& text) {
  try {
    return lab::parseMethods(text);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--methods: ") + e.what());
  }
}

// Every atlas scene, or those named: a bare name is the atlas's scene of that name where there is
// one (pyramid_40 is also a scene of assets/scenes, without criteria), else a scene as elsewhere.
std::vector<std::string> atlasScenePaths(const std::vector<std::string>& scenes) {
  std::vector<std::string> paths;
  if (scenes.empty())
    paths = lab::atlasScenes(assetsDir() + "/scenes/atlas");
  else
    for (const std::string& s : scenes) {
      const std::string atlas = assetsDir() + "/scenes/atlas/" + s + ".json";
      const bool bare = s.find('/') == std::string::npos && scenePath(s) != s;
      paths.push_back(bare && fs::exists(atlas) ? atlas : scenePath(s));
    }
  if (paths.empty()) throw UsageError("no atlas scenes in " + assetsDir() + "/scenes/atlas");
  return paths;
}

void parseClipSize(const std::string& size, int& width, int& height) {
  const size_t x = size.find('x');
  try {
    width = x == std::string::npos ? 0 : std::stoi(size.substr(0, x));
    height = x == std::string::npos ? 0 : std::stoi(size.substr(x + 1));
  } catch (const std::exception&) {
  }
  if (width < 64 || height < 64 || width > 3840 || height > 2160 || width % 2 || height % 2)
    throw UsageError("--size: expected WIDTHxHEIGHT, even, 64x64 to 3840x2160, got \"" + size + "\"");
}

std::unique_ptr<lab::VerdictTable> readExpected(const std::string& path) {
  if (path.empty()) return nullptr;
  try {
    return std::make_unique<lab::VerdictTable>(lab::readVerdicts(path));
  } catch (const std::runtime_error& e) {
    throw UsageError(std::string("--expected: ") + e.what());
  }
}

std::string clipEncoder(bool noClips) {
  if (noClips) return "";
  const std::string ffmpeg = render::findFfmpeg();
  if (ffmpeg.empty()) throw UsageError("clips need ffmpeg, which is not on PATH (Debian: apt-get install ffmpeg); or give --no-clips");
  return ffmpeg;
}

std::vector<SceneResult> loadAtlasScenes(const std::vector<std::string>& paths) {
  std::vector<SceneResult> results;
  for (const std::string& p : paths) {
    SceneResult r;
    r.scene = load(p);
    if (!r.scene.criteria) throw UsageError(p + ": an atlas scene states its pass criteria (a \"criteria\" block)");
    r.error = lab::errorMetric(r.scene);
    results.push_back(std::move(r));
  }
  return results;
}

void checkOutputs(const AtlasOptions& o) {
  const fs::path dir(o.output);
  checkWritable((dir / "index.html").string(), "-o " + o.output);
  if (!o.noClips) checkWritable((dir / "clips" / "x.mp4").string(), "-o " + o.output);
  if (!o.writeExpected.empty()) checkWritable(o.writeExpected, "--write-expected");
  if (!o.record.empty()) checkWritable((fs::path(o.record) / "x.rec").string(), "--record " + o.record);
}

AtlasPlan planAtlas(const AtlasOptions& o) {
  AtlasPlan plan;
  plan.methods = atlasMethods(o.methods);
  const std::vector<std::string> paths = atlasScenePaths(o.scenes);
  parseClipSize(o.size, plan.width, plan.height);
  plan.expected = readExpected(o.expected);
  plan.ffmpeg = clipEncoder(o.noClips);
  plan.results = loadAtlasScenes(paths);
  plan.dir = o.output;
  checkOutputs(o);
  return plan;
}

// --- the runs ---------------------------------------------------------------------------------

// The scene under every method, each cell's record added to `rows`.
void runSceneCells(SceneResult& r, const AtlasPlan& plan, const AtlasOptions& o, std::vector<json>& rows, Progress& progress) {
  try {
    r.cells = lab::runAtlasScene(r.scene, plan.methods, o.noClips ? 0 : o.fps, o.repeat, o.record);
  } catch (const lab::ReferenceError& e) {
    throw UsageError(r.scene.file + ": criteria.reference: " + e.what());
  }
  for (lab::AtlasCell& c : r.cells) {
    if (!c.run.recording.empty()) c.run.recording = relativePath(c.run.recording, o.output);  // as the page links it
    rows.push_back(lab::recordJson(r.scene, c.run, r.scene.criteria->seconds, o.repeat));
    progress.update(static_cast<long long>(rows.size()));
  }
  r.clips.assign(r.cells.size(), "");
  r.panels.assign(r.cells.size(), 0);
}

// Every scene's runs, and its clips before the next scene runs (the states kept for them are then let go).
std::vector<json> runAtlasScenes(AtlasPlan& plan, const AtlasOptions& o, AtlasTimes& times) {
  const double t0 = nowSeconds();
  Progress progress("atlas", static_cast<long long>(plan.results.size() * plan.methods.size()), !o.quiet);
  std::vector<json> rows;
  std::unique_ptr<render::GlRenderer> renderer;
  for (SceneResult& r : plan.results) {
    if (InterruptGuard::interrupted()) throw Interrupted();
    runSceneCells(r, plan, o, rows, progress);
    if (!o.noClips) {
      const double c0 = nowSeconds();
      if (!renderer) renderer = std::make_unique<render::GlRenderer>(plan.width, plan.height);
      writeSceneClips(r, plan.dir, o, *renderer, plan.ffmpeg);
      times.clips += nowSeconds() - c0;
    }
    for (lab::AtlasCell& c : r.cells) std::vector<State>().swap(c.run.frames);
  }
  progress.finish();
  times.physics = nowSeconds() - t0 - times.clips;
  return rows;
}

// Error against cost per scene; a scene's chart is linked when one was drawn. Returns whether any was.
bool writeAtlasCharts(std::vector<SceneResult>& results, const std::vector<json>& rows, const fs::path& dir, bool quiet) {
  std::vector<std::string> charts;
  try {
    charts = writeCharts(rows, lab::ChartOptions{}, (dir / "charts").string(), true);
  } catch (const UsageError& e) {
    if (!quiet) std::cerr << "substep atlas: no charts: " << e.what() << "\n";
  }
  for (SceneResult& r : results) {
    const std::string png = (dir / "charts" / (lab::sceneName(r.scene) + "-pareto.png")).string();
    if (std::find(charts.begin(), charts.end(), png) != charts.end()) r.chart = "charts/" + lab::sceneName(r.scene) + "-pareto.png";
  }
  return !charts.empty();
}

// --- the files --------------------------------------------------------------------------------

json atlasMeta(const AtlasOptions& o, const AtlasTimes& t) {
  return {{"commit", lab::sourceCommit()}, {"source", lab::sourceState()}, {"date_utc", lab::utcNow()},
          {"cpu", lab::cpuModel()},        {"load_average", lab::loadAverage()}, {"physics_seconds", t.physics},
          {"clip_seconds", t.clips},       {"chart_seconds", t.charts},          {"methods", o.methods}};
}

lab::VerdictTable measuredVerdicts(const std::vector<SceneResult>& results) {
  lab::VerdictTable measured;
  for (const SceneResult& r : results)
    for (const lab::AtlasCell& c : r.cells) measured[lab::sceneName(r.scene)][c.run.method.text] = lab::resultName(c.verdict.result);
  return measured;
}

json cellJson(const SceneResult& r, size_t i) {
  const lab::AtlasCell& c = r.cells[i];
  return {{"method", c.run.method.text},
          {"verdict", lab::resultName(c.verdict.result)},
          {"figure", c.verdict.figure},
          {"error", errorText(r, c)},
          {"ms_per_step", c.run.refused ? json(nullptr) : json(c.run.cost.msPerStep)},
          {"wall_seconds", c.wallSeconds},
          {"clip", r.clips[i].empty() ? json(nullptr) : json("clips/" + r.clips[i])},
          {"recording", c.run.recording.empty() ? json(nullptr) : json(c.run.recording)},
          {"panel", r.panels[i]}};
}

json sceneJson(const SceneResult& r) {
  json cells = json::array();
  for (size_t i = 0; i < r.cells.size(); ++i) cells.push_back(cellJson(r, i));
  return {{"scene", lab::sceneName(r.scene)},
          {"file", r.scene.file},
          {"description", r.scene.description},
          {"stresses", r.scene.criteria->stresses},
          {"criteria", criteriaText(r.scene)},
          {"chart", r.chart},
          {"cells", cells}};
}

std::string atlasJsonText(const std::vector<SceneResult>& results, const json& meta, const lab::VerdictTable& measured) {
  json doc = meta;
  doc["scenes"] = json::array();
  for (const SceneResult& r : results) doc["scenes"].push_back(sceneJson(r));
  doc["verdicts"] = lab::verdictsJson(measured);
  return doc.dump(1) + "\n";
}

std::string expectedJsonText(const lab::VerdictTable& measured) {
  return json{{"commit", lab::sourceCommit()},
              {"note", "Expected atlas verdicts (tests/test_atlas.cpp). Rewrite on purpose: substep atlas --no-clips "
                       "--write-expected tests/data/atlas_expected.json -o out/atlas"},
              {"verdicts", lab::verdictsJson(measured)}}
             .dump(1) +
         "\n";
}

void writeAtlasFiles(const AtlasPlan& plan, const AtlasOptions& o, const std::vector<json>& rows, const json& meta) {
  const lab::VerdictTable measured = measuredVerdicts(plan.results);
  writeText((plan.dir / "atlas.json").string(), atlasJsonText(plan.results, meta, measured));
  std::string lines;
  for (const json& r : rows) lines += r.dump() + "\n";
  writeText((plan.dir / "atlas.jsonl").string(), lines);
  writeText((plan.dir / "atlas.md").string(), "Measured at commit " + lab::sourceCommit() + " (" + lab::utcNow() +
                                                  "), `substep atlas`:\n\n" + markdownTable(plan.results, plan.methods));
  if (!o.writeExpected.empty()) writeText(o.writeExpected, expectedJsonText(measured));
  writePage(plan.results, plan.methods, meta, plan.expected.get(), (plan.dir / "index.html").string());
}

void printSummary(const AtlasPlan& plan, const AtlasOptions& o, const AtlasTimes& t, bool charts) {
  std::cout << "\n" << markdownTable(plan.results, plan.methods) << "\n"
            << "physics   " << fixed(t.physics, 1) << " s; clips " << fixed(t.clips, 1) << " s; charts " << fixed(t.charts, 1)
            << " s\nwrote     " << (plan.dir / "index.html").string() << ", atlas.json, atlas.jsonl, atlas.md"
            << (o.noClips ? "" : ", clips/") << (charts ? ", charts/" : "") << "\n";
  if (!o.writeExpected.empty()) std::cout << "wrote     " << o.writeExpected << "\n";
  if (!o.record.empty()) std::cout << "wrote     a recording of every run in " << o.record << "\n";
}

int runAtlas(const AtlasOptions& o) {
  AtlasPlan plan = planAtlas(o);
  if (!o.quiet)
    std::cout << "atlas     " << plan.results.size() << " scenes x " << plan.methods.size() << " methods"
              << (o.noClips ? "" : ", with clips") << " -> " << o.output << "\n";
  InterruptGuard interrupt;
  AtlasTimes times;
  const std::vector<json> rows = runAtlasScenes(plan, o, times);
  const double c0 = nowSeconds();
  const bool charts = writeAtlasCharts(plan.results, rows, plan.dir, o.quiet);
  times.charts = nowSeconds() - c0;
  writeAtlasFiles(plan, o, rows, atlasMeta(o, times));
  if (!o.quiet) printSummary(plan, o, times, charts);
  return 0;
}

}  // namespace

void addAtlasCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<AtlasOptions>();
  CLI::App* cmd = app.add_subcommand("atlas", "Run the failure atlas: every atlas scene under every method, judged by its "
                                              "criteria; an HTML page with clips and charts");
  cmd->footer(std::string("\nDefault methods: ") + lab::defaultAtlasMethods() +
              "\nThe verdicts come from the physics runs alone; tests/test_atlas.cpp holds the expected table "
              "(tests/data/atlas_expected.json).");
  cmd->add_option("-o,--output", opt->output, "The folder to write index.html, atlas.json, clips/ and charts/ into")->required();
  cmd->add_option("--scenes", opt->scenes, "Atlas scenes, comma-separated (default: every file in assets/scenes/atlas)")
      ->delimiter(',');
  cmd->add_option("--methods", opt->methods, "Methods, comma-separated specs (default: the set above)");
  cmd->add_flag("--no-clips", opt->noClips, "Do not render the clips (the verdicts and charts only)");
  cmd->add_option("--clip-seconds", opt->clipSeconds, "Length of each clip, simulated [s] (default 2)")->check(finiteIn(0.05, 60));
  cmd->add_option("--fps", opt->fps, "Clip frames per simulated second (default 30)")->check(CLI::Range(1, 120));
  cmd->add_option("--size", opt->size, "Clip size WIDTHxHEIGHT (default 960x540: four panels of 480x270)");
  cmd->add_option("--repeat", opt->repeat, "Timed runs of each cell; the cost is their median (default 1)")->check(CLI::Range(1, 100));
  cmd->add_option("--expected", opt->expected, "Mark cells whose verdict differs from this table (e.g. tests/data/atlas_expected.json)");
  cmd->add_option("--write-expected", opt->writeExpected, "Write the measured verdicts as an expected table to this file");
  cmd->add_option("--record", opt->record,
                  "Write a recording of every cell's run into this folder (<scene>-<method>.rec; atlas.json and "
                  "atlas.jsonl name each as \"recording\", relative to -o; docs/recordings.md)");
  cmd->add_flag("--quiet,-q", opt->quiet, "Print nothing but errors");
  cmd->callback([opt, &action] { action = [opt] { return runAtlas(*opt); }; });
}

}  // namespace substep::app
