// substep sweep: the cross product of scenes x methods x time steps, one JSON record per run
// (lab/record.h) appended to a JSONL file; resumable, shardable, mergeable (docs/lab.md).
#include "app/commands.h"
#include "app/common.h"
#include "app/sweep_command.h"
#include "lab/record.h"
#include "lab/sweep.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <set>

namespace substep::app {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct MergeOptions {
  std::vector<std::string> inputs;
  std::string output;
  bool allowGaps = false;
  bool quiet = false;
};

// The output so far: its keys, and a last line cut short removed (rewritten atomically).
std::set<std::string> resume(const std::string& output) {
  std::set<std::string> keys;
  std::error_code ec;
  if (!fs::exists(output, ec)) return keys;
  if (!fs::is_regular_file(output, ec)) throw UsageError("-o " + output + ": not a regular file");
  bool truncated = false;
  std::vector<json> rows;
  try {
    rows = lab::readRows(output, &truncated);
  } catch (const std::runtime_error& e) {
    throw UsageError(std::string("-o: ") + e.what() + "; give a new file, or the output of an earlier sweep to resume it");
  }
  if (truncated) {
    AtomicFile f(output);
    for (const json& r : rows) f.out() << r.dump() << '\n';
    f.commit();
  }
  for (const json& r : rows) keys.insert(r["key"].get<std::string>());
  return keys;
}

// One line, in one write(2) to a file opened for appending: a sweep stopped at any moment leaves
// whole lines behind (or a last one cut short, which resuming removes).
class RowWriter {
 public:
  explicit RowWriter(const std::string& path) : path_(path) {
    checkWritable(path, "-o " + path);
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (fd_ < 0) throw UsageError("-o " + path + ": cannot open: " + std::strerror(errno));
  }
  ~RowWriter() {
    if (fd_ >= 0) ::close(fd_);
  }
  void write(const json& row) {
    const std::string line = row.dump() + "\n";
    size_t done = 0;
    while (done < line.size()) {
      const ssize_t n = ::write(fd_, line.data() + done, line.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) throw std::runtime_error(path_ + ": write failed: " + std::strerror(errno));
      done += static_cast<size_t>(n);
    }
  }

 private:
  std::string path_;
  int fd_ = -1;
};

std::string shortFigure(const json& row) {
  if (row["refused"].get<bool>()) return "refused: " + row["stopped"].get<std::string>();
  std::string s;
  if (row["error"]["value"].is_number())
    s = row["error"]["label"].get<std::string>() + " " +
        lab::formatMetric(row["error"]["metric"].get<std::string>(), row["error"]["value"].get<double>());
  if (row["diverged"].get<bool>()) s += (s.empty() ? "" : "; ") + std::string("DIVERGED");
  if (row.contains("verdict")) s += (s.empty() ? "" : "; ") + row["verdict"]["result"].get<std::string>();
  return s;
}

// --- the plan: the spec, its flags and every scene checked before the first run ---------------

lab::SweepSpec readSpec(const std::string& file) {
  if (file.empty()) return {};
  try {
    return lab::readSweepSpec(file);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

std::vector<double> parseSteps(const std::vector<std::string>& dts) {
  std::vector<double> steps;
  for (const std::string& d : dts) try {
      steps.push_back(lab::parseStep(d));
    } catch (const std::invalid_argument& e) {
      throw UsageError("--dt: " + std::string(e.what()));
    }
  return steps;
}

// The spec file's fields, each replaced by its flag when given.
lab::SweepSpec sweepSpec(const SweepOptions& o) {
  lab::SweepSpec spec = readSpec(o.spec);
  if (!o.scenes.empty()) spec.scenes = o.scenes;
  if (!o.methods.empty()) spec.methods = o.methods;
  if (!o.dts.empty()) spec.dts = parseSteps(o.dts);
  if (o.repeat) spec.repeat = *o.repeat;
  if (o.seconds) spec.seconds = o.seconds;
  if (spec.scenes.empty()) throw UsageError("no scenes: give SPEC.json or --scenes (e.g. --scenes chain,pyramid)");
  if (spec.methods.empty()) throw UsageError("no methods: give SPEC.json or --methods (e.g. --methods a2:m=4,a5:n=4)");
  for (const std::string& m : spec.methods) try {
      lab::parseMethods(m);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--methods: ") + e.what());
    }
  return spec;
}

lab::Shard shardOption(const std::string& text) {
  try {
    return text.empty() ? lab::Shard{} : lab::parseShard(text);
  } catch (const std::invalid_argument& e) {
    throw UsageError("--shard: " + std::string(e.what()));
  }
}

lab::SweepPlan planRuns(const lab::SweepSpec& spec) {
  std::vector<Scene> scenes;
  for (const std::string& name : spec.scenes) {
    try {
      scenes.push_back(lab::loadSweepScene(scenePath(name), spec.reference));
    } catch (const SceneError& e) {
      throw UsageError(std::string(e.what()));
    }
  }
  try {
    return lab::planSweep(spec, std::move(scenes));
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

// The shard's runs, and those of them not yet in the output.
struct ShardRuns {
  size_t mine = 0;
  std::vector<size_t> todo;
};

ShardRuns shardRuns(const lab::SweepPlan& plan, const lab::Shard& shard, const std::set<std::string>& done) {
  ShardRuns s;
  for (size_t k = 0; k < plan.runs.size(); ++k) {
    if (!shard.has(static_cast<long long>(k))) continue;
    ++s.mine;
    if (!done.count(plan.runs[k].key)) s.todo.push_back(k);
  }
  return s;
}

void printSweepHeader(const SweepOptions& o, const lab::SweepSpec& spec, const lab::SweepPlan& plan, const lab::Shard& shard,
                      const ShardRuns& runs) {
  size_t methods = 0;
  for (const std::string& m : spec.methods) methods += lab::parseMethods(m).size();
  const size_t steps = std::max<size_t>(1, spec.dts.size());
  auto count = [](size_t n, const char* what) { return std::to_string(n) + " " + what + (n == 1 ? "" : "s"); };
  std::cout << "sweep     " << count(plan.runs.size(), "run") << " (" << count(plan.scenes.size(), "scene") << " x "
            << count(methods, "method") << " x " << count(steps, "time step") << "), plan " << plan.id;
  if (shard.count > 1) std::cout << "; shard " << shard.index << "/" << shard.count << ": " << runs.mine << " runs";
  std::cout << "; " << (runs.mine - runs.todo.size()) << " already in " << o.output << ", " << runs.todo.size() << " to run\n";
}

// --- the runs ---------------------------------------------------------------------------------

// A scene's reference, prepared when a run first needs it: a resumed sweep with nothing left on the scene skips it.
const lab::PreparedReference* referenceFor(const Scene& scene, double seconds, std::optional<lab::PreparedReference>& ref) {
  if (!ref && scene.criteria && scene.criteria->reference) {
    try {
      ref = lab::prepareReference(scene, *scene.criteria->reference, seconds);
    } catch (const std::exception& e) {  // a converged run that is not, a pendulum that cannot swing
      throw UsageError(scene.file + ": criteria.reference: " + e.what());
    }
  }
  return ref ? &*ref : nullptr;
}

lab::RunResult runPlanned(const lab::PlannedRun& run, const Scene& scene, int repeat, const lab::PreparedReference* reference,
                          const std::string& recording) {
  lab::RunSetup setup;
  setup.recording = recording;
  setup.seconds = run.seconds;
  setup.repeat = repeat;
  setup.dt = run.dt;
  setup.reference = reference;
  setup.stop = [](const lab::Metrics&, double) { return InterruptGuard::interrupted() ? std::string("interrupted") : ""; };
  return lab::runMethod(scene, run.method, setup);
}

void printRow(long long n, size_t total, const Scene& scene, const lab::PlannedRun& run, const lab::RunResult& result,
              const json& row) {
  char cost[64];
  std::snprintf(cost, sizeof cost, "%.4g ms/step", result.cost.msPerStep);
  std::cout << "[" << n << "/" << total << "] " << lab::sceneName(scene) << "  " << run.method.text << "  h="
            << stepText(result.settings.dt) << ": " << (result.refused ? "-" : cost) << ", " << shortFigure(row) << "\n"
            << std::flush;
}

// Each run's recording in `dir` (recordingFileName; the run's index added to a name two runs would share).
std::vector<std::string> recordingPaths(const lab::SweepPlan& plan, const std::string& dir) {
  std::vector<std::string> paths(plan.runs.size());
  if (dir.empty()) return paths;
  std::set<std::string> taken;
  for (size_t k = 0; k < plan.runs.size(); ++k) {
    const lab::PlannedRun& r = plan.runs[k];
    std::string name = lab::recordingFileName(plan.scenes[r.scene], r.method.text, r.dt);
    if (!taken.insert(name).second) {
      name = name.substr(0, name.size() - 4) + "-" + std::to_string(k + 1) + ".rec";
      taken.insert(name);
    }
    paths[k] = (fs::path(dir) / name).string();
  }
  return paths;
}

// Runs `todo`, a row each written as it ends; returns how many.
long long runAll(const lab::SweepPlan& plan, const std::vector<size_t>& todo, int repeat, RowWriter& writer, const SweepOptions& o) {
  const bool quiet = o.quiet;
  const std::vector<std::string> recordings = recordingPaths(plan, o.record);
  std::vector<std::optional<lab::PreparedReference>> references(plan.scenes.size());
  Progress progress("sweep", static_cast<long long>(todo.size()), !quiet);
  long long n = 0;
  for (size_t k : todo) {
    if (InterruptGuard::interrupted()) throw Interrupted();
    const lab::PlannedRun& run = plan.runs[k];
    const Scene& scene = plan.scenes[run.scene];
    const lab::RunResult result =
        runPlanned(run, scene, repeat, referenceFor(scene, run.seconds, references[run.scene]), recordings[k]);
    if (InterruptGuard::interrupted()) throw Interrupted();  // the run was cut: no row for it
    json row = lab::recordJson(scene, result, run.seconds, repeat,
                               lab::SweepPlace{plan.id, static_cast<long long>(k), static_cast<long long>(plan.runs.size())});
    if (!result.recording.empty()) row["recording"] = relativePath(result.recording, fs::path(o.output).parent_path().string());
    writer.write(row);
    ++n;
    if (!quiet) {
      progress.clear();
      printRow(n, todo.size(), scene, run, result, row);
    }
    progress.update(n);
  }
  progress.finish();
  return n;
}


int runMerge(const MergeOptions& o) {
  std::vector<std::vector<json>> files;
  for (const std::string& in : o.inputs) {
    if (samePath(in, o.output)) throw UsageError(in + " is also the output; give the merged file another name");
    if (const std::string why = checkInputFile(in, size_t(1) << 34); !why.empty()) throw UsageError(in + ": " + why);
    bool truncated = false;
    try {
      files.push_back(lab::readRows(in, &truncated));
    } catch (const std::runtime_error& e) {
      throw UsageError(e.what());
    }
    if (truncated && !o.quiet) std::cerr << "substep sweep merge: " << in << ": its last line is cut short; left out\n";
  }
  const lab::MergeResult m = lab::mergeRows(files);
  for (const std::string& d : m.duplicates)
    std::cerr << "substep sweep merge: duplicate run (kept the first): " << d << "\n";
  for (const std::string& g : m.gaps) std::cerr << "substep sweep merge: gap: " << g << "\n";
  if (!m.gaps.empty() && !o.allowGaps) {
    std::cerr << "substep sweep merge: not written: runs are missing (run the missing shards, or --allow-gaps)\n";
    return kExitFailure;
  }
  AtomicFile out(o.output);
  for (const json& r : m.rows) out.out() << r.dump() << '\n';
  out.commit();
  if (!o.quiet)
    std::cout << "merged    " << m.rows.size() << " rows from " << o.inputs.size() << " files into " << o.output << " ("
              << m.duplicates.size() << " duplicates, " << m.gaps.size() << " plans with gaps)\n";
  return 0;
}

}  // namespace

int runSweep(const SweepOptions& o) {
  const lab::SweepSpec spec = sweepSpec(o);
  const lab::Shard shard = shardOption(o.shard);
  const lab::SweepPlan plan = planRuns(spec);
  const std::set<std::string> done = resume(o.output);
  RowWriter writer(o.output);
  if (!o.record.empty()) checkWritable((fs::path(o.record) / "x.rec").string(), "--record " + o.record);
  const ShardRuns runs = shardRuns(plan, shard, done);
  if (!o.quiet) printSweepHeader(o, spec, plan, shard, runs);
  InterruptGuard interrupt;
  const long long n = runAll(plan, runs.todo, spec.repeat, writer, o);
  if (!o.quiet)
    std::cout << "wrote     " << o.output << " (" << n << " new rows)" << (o.record.empty() ? "" : "; recordings in " + o.record)
              << "\n";
  return 0;
}

void addSweepCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<SweepOptions>();
  CLI::App* cmd = app.add_subcommand(
      "sweep", "Run scenes x methods x time steps and write one JSON record per run (JSONL); resumable and shardable");
  cmd->footer(
      "\nMethods are the --compare spec language with value lists (a grid): a2:m=4|10, a5:n=1|2|4|8:m=1, "
      "bullet:it=10.\nSPEC.json: {\"scenes\": [...], \"methods\": [...], \"dt\": [\"1/60\"], \"repeat\": 3, \"seconds\": "
      "2, \"reference\": {...}};\nflags replace its fields. Runs already in OUT are skipped, so a stopped sweep resumes. "
      "See docs/lab.md.");
  cmd->add_option("spec", opt->spec, "A sweep spec (JSON); optional when --scenes and --methods are given");
  cmd->add_option("--scenes", opt->scenes, "Scenes, comma-separated: names in assets/scenes (chain, atlas/card_house) or .json paths")
      ->delimiter(',');
  cmd->add_option("--methods", opt->methods, "Methods, comma-separated specs, e.g. a2:m=4,a5:n=1|2|4:m=1,bullet:it=10")
      ->delimiter(',');
  cmd->add_option("--dt", opt->dts, "Time steps, comma-separated (1/60,1/120): every method at each, unless it names its h")
      ->delimiter(',');
  cmd->add_option("--repeat", opt->repeat, "Timed runs of each run; the cost is their median (default 1)")->check(CLI::Range(1, 1000));
  cmd->add_option("--seconds", opt->seconds, "Simulated time of each run [s] (default: each scene's criteria, else 3)")
      ->check(finiteIn(1e-3, 3600));
  cmd->add_option("-o,--output", opt->output, "The JSONL file the records are appended to")->required();
  cmd->add_option("--shard", opt->shard, "i/N: run only every N-th run of the plan, starting at the i-th (1 <= i <= N)");
  cmd->add_option("--record", opt->record,
                  "Write a recording of every run into this folder (<scene>-<method>.rec; each record names its own as "
                  "\"recording\", relative to the output's folder; docs/recordings.md)");
  cmd->add_flag("--quiet,-q", opt->quiet, "Print nothing but errors (no progress bar either)");
  addMaxBodies(*cmd, opt->limits);

  auto merge = std::make_shared<MergeOptions>();
  CLI::App* m = cmd->add_subcommand("merge", "Merge sweep outputs (shards) into one file, checking for gaps and duplicates");
  m->footer("\nRows are told apart by their key (scene, method, h, seconds, reference); a run found twice is kept once.\n"
            "Each row names its sweep's plan and its index there: a plan with runs missing is named and nothing is\n"
            "written (exit status 1) unless --allow-gaps. See docs/lab.md.");
  m->add_option("inputs", merge->inputs, "The JSONL files to merge")->required();
  m->add_option("-o,--output", merge->output, "The merged JSONL file (written atomically)")->required();
  m->add_flag("--allow-gaps", merge->allowGaps, "Write the merged file even when runs of a plan are missing");
  m->add_flag("--quiet,-q", merge->quiet, "Print nothing but errors");
  m->callback([merge, &action] { action = [merge] { return runMerge(*merge); }; });

  cmd->callback([opt, m, &action] {
    if (m->parsed()) return;
    if (opt->output.empty()) throw CLI::RequiredError("--output");
    action = [opt] { return runSweep(*opt); };
  });
  // -o is required for a sweep; merge has its own.
  cmd->get_option("--output")->required(false);
}

}  // namespace substep::app
