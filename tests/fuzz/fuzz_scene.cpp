// libFuzzer target: a scene file from bytes, through the parser and a few steps of every
// algorithm. What must hold for every input (docs/robustness.md): no crash, no sanitizer report,
// no hang (libFuzzer's -timeout), and no exception but the parser's SceneError, which the
// program turns into exit status 2 with the file and the JSON path.
//   build: scripts/test --fuzz (clang 14, -fsanitize=fuzzer,address,undefined)
//   long campaign: scripts/fuzz
#include "physics/scene_file.h"
#include "physics/run.h"
#include "physics/world.h"

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#ifndef SUBSTEP_SOURCE_DIR
#define SUBSTEP_SOURCE_DIR "."
#endif

namespace {

[[noreturn]] void finding(const char* where, const std::string& what) {
  std::fprintf(stderr, "fuzz_scene: %s: %s\n", where, what.c_str());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace substep;
  const std::string text(reinterpret_cast<const char*>(data), size);
  SceneLimits lim;
  lim.maxBodies = 64;  // the cap itself is tested elsewhere; here inputs stay quick to step
  Scene scene;
  try {
    // Mesh paths resolve as for the shipped scenes (../meshes/gem.obj).
    scene = parseScene(text, "fuzz.json", SUBSTEP_SOURCE_DIR "/assets/scenes", lim);
  } catch (const SceneError&) {
    return 0;  // bad input, reported with its path: the contract
  } catch (const std::exception& e) {
    finding("parse", e.what());
  }
  for (Algorithm a : kAlgorithms) {
    SolverOverrides o = scene.solver;
    o.set(&SolverSettings::algorithm, a);
    SolverSettings settings;
    try {
      settings = resolve(o);
    } catch (const std::invalid_argument&) {
      continue;  // e.g. a preset with a1: the command line reports it (exit 2)
    }
    // A1's dense solve is O(rows³) within a work budget of seconds per step (mlcp_direct.h):
    // right for the program, too slow for a fuzzer under sanitizers (10x slower).
    settings.directMaxRows = 64;
    settings.directWorkBudget = 2e8;
    try {
      World world(scene.model, settings, scene.initial);
      WorldEngine engine(world);
      RunDriver run(engine, 3);
      // Ends planned, diverged or overloaded (exit status 3 or 2), or refused by A1 beyond its
      // size or budget (exit 2): each is a reported outcome, not a finding.
      run.run();
    } catch (const std::exception& e) {
      finding(algorithmName(a), e.what());
    }
  }
  return 0;
}
