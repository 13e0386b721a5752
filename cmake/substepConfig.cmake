# substep's CMake package (docs/install.md):
#   find_package(substep 0.1 CONFIG REQUIRED)
# gives the libraries substep::physics, substep::render and substep::lab, the program
# substep::substep and substep_add_snapshot_test() (SubstepSnapshotTest.cmake).
# The libraries are shared: only what their public headers include is looked for here
# (physics: Eigen, FCL, nlohmann-json; render: stb_truetype and threads); what they link
# privately (assimp, OSMesa, Bullet, ...) their own Debian packages bring at run time.
include(CMakeFindDependencyMacro)
find_dependency(Eigen3 3.4 NO_MODULE)
find_dependency(fcl)
find_dependency(nlohmann_json 3.10)
find_dependency(Threads)
if(NOT TARGET PkgConfig::STB)
  find_dependency(PkgConfig)
  pkg_check_modules(STB QUIET IMPORTED_TARGET stb)
  if(NOT TARGET PkgConfig::STB)
    set(substep_FOUND FALSE)
    set(substep_NOT_FOUND_MESSAGE "substep's render headers need stb (Debian package libstb-dev): pkg-config found no stb")
    return()
  endif()
endif()
include(${CMAKE_CURRENT_LIST_DIR}/substepTargets.cmake)
include(${CMAKE_CURRENT_LIST_DIR}/SubstepSnapshotTest.cmake)
