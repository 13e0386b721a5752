// libFuzzer target: a scene file from bytes, through the parser and a few steps of every
// algorithm. What must hold for every input (docs/robustness.md): no crash, no sanitizer report,
// no hang (libFuzzer's -timeout), and no exception but the parser's SceneError, which the
// program turns into exit status 2 with the file and the JSON path.
//   build: scripts/test --fuzz (clang 14, -fsanitize=fuzzer,address,undefined)
//   long campaign: scripts/fuzz
#include "physics/scene_file.h"
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
  for (Algorithm a : {Algorithm::A1, Algorithm::A2, Algorithm::A3, Algorithm::A4, Algorithm::A5, Algorithm::Soft}) {
    SolverOverrides o = scene.solver;
    o.algorithm = a;
    SolverSettings settings;
    try {
      settings = resolve(o);
    } catch (const std::invalid_argument&) {
      continue;  // e.g. a preset with a1: the command line reports it (exit 2)
    }
    // A1's dense solve is O(rows³) within a work budget of seconds per step (mlcp_direct.h):
    // right for the program, too slow for a fuzzer under sanitizers (10x slower), where three
    // steps of a hard problem at the full budget took 11 s (the 2026-12-01 campaign's finding).
    settings.directMaxRows = 64;
    settings.directWorkBudget = 2e8;
    try {
      World world(scene.model, settings, scene.initial);
      for (int k = 0; k < 3; ++k) {
        const StepReport& r = world.step();
        if (!r.finite) break;  // diverged or overloaded: reported with exit status 3 (or 2)
      }
    } catch (const std::runtime_error& e) {
      // A1's dense problem has a size limit the program reports (exit 1, "use --algo a2..a5").
      if (a == Algorithm::A1 && std::string(e.what()).find("dense") != std::string::npos) continue;
      finding(algorithmName(a), e.what());
    } catch (const std::exception& e) {
      finding(algorithmName(a), e.what());
    }
  }
  return 0;
}
