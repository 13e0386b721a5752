// substep-scrub-bench: how long the viewer takes to show a kept step it is scrubbed to: from the
// request (LiveSession::seek, what POST .../scrub calls) to the first published JPEG frame of that
// step, on the live session the server runs (drawn at the server's size, encoded as the stream
// sends it). HTTP on loopback adds about a millisecond on top and is left out. docs/server.md,
// "Scrubbing", states what it measured.
//
// Method: per scene, a live session with one viewer plays --seconds of simulated time (paced as
// fast as it can: a seek forward), keeping every step; then --scrubs times a kept step drawn at
// random (a fixed seed, so runs compare), each scrub timed on its own. Reported: median, 90th
// percentile and max [ms], and whether the median is within --limit.
// Exit status: 0 done (and within the limit), 1 beyond it or a failure, 2 bad input.
#include "app/common.h"
#include "app/render_options.h"
#include "render/live_session.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <random>
#include <string>
#include <vector>

namespace substep::app {
namespace {

using namespace substep::render;
using Clock = std::chrono::steady_clock;

struct Options {
  std::vector<std::string> scenes = {"pyramid", "ragdoll_pile"};
  double seconds = 10;
  int scrubs = 30;
  std::string size = "1280x720";
  double limit = 100;  // [ms]
};

double percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(std::min<double>(v.size() - 1, std::floor(q * static_cast<double>(v.size() - 1) + 0.5)))];
}

// Median of the scene's scrubs [ms]; prints the line.
double benchScene(const Options& o, const std::string& name, int width, int height) {
  auto scene = std::make_shared<const Scene>(loadScene(assetsDir() + "/scenes/" + name + ".json"));
  LiveConfig c;
  c.width = width;
  c.height = height;
  c.timeline = {o.seconds + 1, size_t{8} << 30};
  Look look;
  look.camera = chooseCamera(*scene, {});
  LiveSession s(scene, {{resolveSettings(*scene, {}), ""}}, look, c);
  LiveSession::Viewer viewer(s);  // frames are drawn while someone watches
  s.seek(o.seconds);
  while (s.waitStats(0, 1.0).seeking || s.stats().shown + 1e-9 < o.seconds - 0.5 / 60) s.waitStats(s.stats().seq, 1.0);
  const long long kept = s.read([](const RenderSession& r, const Look&) { return static_cast<long long>(r.panel(0).history().size()); });
  const double dt = s.read([](const RenderSession& r, const Look&) { return r.panel(0).settings().dt; });
  std::mt19937 rng(7);
  std::uniform_int_distribution<long long> pick(0, kept - 2);  // not the newest: that one is shown
  std::vector<double> ms;
  LiveFrame f = s.waitFrame(0, 5.0);
  for (int k = 0; k < o.scrubs; ++k) {
    const double target = static_cast<double>(pick(rng)) * dt;
    const auto t0 = Clock::now();
    s.seek(target);
    const double shown = s.read([](const RenderSession& r, const Look&) { return r.time(); });
    do f = s.waitFrame(f.seq, 5.0);
    while (f.seq != 0 && std::abs(f.time - shown) > 1e-9 &&
           std::chrono::duration<double>(Clock::now() - t0).count() < 10);
    if (f.seq == 0 || std::abs(f.time - shown) > 1e-9) throw std::runtime_error(name + ": no frame of t = " + std::to_string(shown) + " s within 10 s");
    ms.push_back(1e3 * std::chrono::duration<double>(Clock::now() - t0).count());
  }
  const double median = percentile(ms, 0.5);
  std::cout << name << ": " << scene->model.dynamicCount() << " bodies, " << kept << " kept steps, " << o.scrubs
            << " scrubs at " << width << "x" << height << ": median " << median << " ms, p90 " << percentile(ms, 0.9)
            << " ms, max " << percentile(ms, 1.0) << " ms (limit " << o.limit << " ms: " << (median <= o.limit ? "within" : "BEYOND")
            << ")" << std::endl;
  return median;
}

}  // namespace
}  // namespace substep::app

int main(int argc, char** argv) {
  using namespace substep::app;
  Options o;
  CLI::App app("substep-scrub-bench: from a scrub request to the first streamed frame of the kept step (docs/server.md)");
  app.add_option("--scenes", o.scenes, "Scene names in assets/scenes (default pyramid ragdoll_pile)");
  app.add_option("--seconds", o.seconds, "Simulated time played and kept before scrubbing [s] (default 10)")
      ->check(CLI::Range(0.1, 600.0));
  app.add_option("--scrubs", o.scrubs, "Scrubs to time per scene (default 30)")->check(CLI::Range(1, 10000));
  app.add_option("--size", o.size, "Frame size WIDTHxHEIGHT (default 1280x720, the server's)");
  app.add_option("--limit", o.limit, "The median to stay within [ms] (default 100)")->check(CLI::Range(1.0, 1e6));
  CLI11_PARSE(app, argc, argv);
  try {
    int w = 0, h = 0;
    parseFrameSize(o.size, w, h);
    bool within = true;
    for (const std::string& name : o.scenes) within = benchScene(o, name, w, h) <= o.limit && within;
    return within ? 0 : 1;
  } catch (const UsageError& e) {
    std::cerr << "substep-scrub-bench: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "substep-scrub-bench: " << e.what() << "\n";
    return 1;
  }
}
