// Writes the recording fuzzer's seeds into a folder: short recordings of shipped scenes (a box on
// the ground, a ragdoll with its joints, the stack), made by the writer itself, so that the seeds
// follow the format as it is built rather than a committed copy of it.
//   make_recording_seeds DIR
#include "physics/recording.h"
#include "physics/settings_json.h"
#include "physics/world.h"

#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

#ifndef SUBSTEP_SOURCE_DIR
#define SUBSTEP_SOURCE_DIR "."
#endif

int main(int argc, char** argv) {
  using namespace substep;
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_recording_seeds DIR\n");
    return 2;
  }
  try {
    std::filesystem::create_directories(argv[1]);
    const struct {
      const char* scene;
      long long steps, every;
    } seeds[] = {{"box_on_ground", 8, 1}, {"ragdoll", 4, 1}, {"stack", 10, 5}};
    for (const auto& s : seeds) {
      const Scene scene = loadScene(std::string(SUBSTEP_SOURCE_DIR "/assets/scenes/") + s.scene + ".json");
      const SolverSettings settings = resolve(scene.solver);
      const nlohmann::json meta = {{"format", "substep-recording"},
                                   {"version", kRecordingVersion},
                                   {"scene", {{"file", scene.file}, {"base_dir", scene.baseDir}, {"text", scene.text}}},
                                   {"bodies", scene.model.bodies.size()},
                                   {"joints", scene.model.joints.size()},
                                   {"panels", {{{"name", ""}, {"settings", settingsJson(settings)}}}},
                                   {"every", s.every},
                                   {"planned_steps", s.steps}};
      World world(scene.model, settings, scene.initial);
      WorldEngine engine(world);
      RunDriver run(engine, s.steps);
      RecordingWriter w(std::string(argv[1]) + "/" + s.scene + ".rec", meta);
      RecordingObserver rec(w, scene.model, 0, s.every, s.steps);
      run.add(rec).run();
      w.commit();
      std::printf("wrote %s (%llu bytes)\n", w.path().c_str(), static_cast<unsigned long long>(w.bytes()));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_recording_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
