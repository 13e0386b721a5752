// top_box SCENE [SECONDS]: steps a scene with its own solver settings and prints the height of its
// highest dynamic body at the end (stack.json: the top box, 4.5 m when the stack stands).
#include "physics/scene_file.h"
#include "physics/settings.h"
#include "physics/world.h"

#include <cstdio>
#include <cstdlib>
#include <exception>

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: top_box SCENE.json [SECONDS]\n");
    return 2;
  }
  try {
    const substep::Scene scene = substep::loadScene(argv[1]);
    const double seconds = argc > 2 ? std::atof(argv[2]) : 2.0;
    substep::World world(scene.model, substep::resolveFor(scene.solver, {}), scene.initial);
    while (world.state().time < seconds - 1e-9) world.step();
    double top = -1e300;
    for (size_t i = 0; i < scene.model.bodies.size(); ++i)
      if (!scene.model.bodies[i].isStatic && world.state().bodies[i].x.y() > top) top = world.state().bodies[i].x.y();
    std::printf("%.4f\n", top);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "top_box: %s\n", e.what());
    return 1;
  }
}
