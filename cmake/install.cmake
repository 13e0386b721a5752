# What `cmake --install BUILD --prefix P` installs (docs/install.md): the programs, the three
# libraries with their headers, a CMake package (substepConfig.cmake: substep::physics,
# substep::render, substep::lab, substep::substep and substep_add_snapshot_test), a pkg-config
# file per library, the assets the programs read, the docs; and `cpack -G DEB`'s package.
# The same package is written into the build folder, so that a project can use a build of substep
# without installing it (-Dsubstep_DIR=BUILD).
if(NOT BUILD_SHARED_LIBS)
  message(STATUS "substep: static libraries (BUILD_SHARED_LIBS=OFF): no install rules, no package")
  return()
endif()
include(CMakePackageConfigHelpers)
set(SUBSTEP_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/substep)

install(TARGETS physics lab render substep EXPORT substepTargets
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
if(SUBSTEP_BENCH)
  install(TARGETS substep-bench substep-render-bench substep-scrub-bench RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
file(RELATIVE_PATH SUBSTEP_PC_TO_PREFIX /${CMAKE_INSTALL_LIBDIR}/pkgconfig /)  # relocatable: ../..
foreach(lib physics lab render)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${lib}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/substep/${lib}
    FILES_MATCHING PATTERN "*.h")
  configure_file(${PROJECT_SOURCE_DIR}/cmake/substep-${lib}.pc.in ${PROJECT_BINARY_DIR}/pkgconfig/substep-${lib}.pc @ONLY)
  install(FILES ${PROJECT_BINARY_DIR}/pkgconfig/substep-${lib}.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
endforeach()
# Scenes (with the meshes they name relatively), sweep specs, the server's page, the snapshot
# example; the programs find them at PREFIX/share/substep/assets (app/common.cpp, assetsDir()).
install(DIRECTORY ${PROJECT_SOURCE_DIR}/assets/ DESTINATION ${CMAKE_INSTALL_DATADIR}/substep/assets)
install(PROGRAMS ${PROJECT_SOURCE_DIR}/scripts/sweep-slurm.sh DESTINATION ${CMAKE_INSTALL_DATADIR}/substep)
install(FILES ${PROJECT_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR})

# The CMake package, installed and in the build folder.
install(EXPORT substepTargets NAMESPACE substep:: DESTINATION ${SUBSTEP_CMAKE_DIR})
export(EXPORT substepTargets NAMESPACE substep:: FILE ${PROJECT_BINARY_DIR}/substepTargets.cmake)
# 0.x: a minor version may change the API, so find_package(substep 0.1) takes 0.1.* only.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/substepConfigVersion.cmake COMPATIBILITY SameMinorVersion)
configure_file(${PROJECT_SOURCE_DIR}/cmake/substepConfig.cmake ${PROJECT_BINARY_DIR}/substepConfig.cmake COPYONLY)
configure_file(${PROJECT_SOURCE_DIR}/cmake/SubstepSnapshotTest.cmake ${PROJECT_BINARY_DIR}/SubstepSnapshotTest.cmake COPYONLY)
install(FILES ${PROJECT_BINARY_DIR}/substepConfig.cmake ${PROJECT_BINARY_DIR}/substepConfigVersion.cmake
  ${PROJECT_SOURCE_DIR}/cmake/SubstepSnapshotTest.cmake DESTINATION ${SUBSTEP_CMAKE_DIR})

# cpack -G DEB (in the build folder): one package with everything above under /usr. Depends are
# computed from the ELF files (dpkg-shlibdeps), plus the font the renderer draws its text with.
# Recommends: what videos (ffmpeg) and charts (gnuplot) need, and what the headers include, for
# building against the package.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME substep)
set(CPACK_PACKAGE_VENDOR substep)
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "rigid-body physics lab: Havok-style sub-stepping, rendering, sweeps")
set(CPACK_PACKAGE_DESCRIPTION "substep steps rigid-body scenes under the sub-stepping constraint solver of
 Nohra's report on Havok's physics solver, Box2D-v3-style soft steps and Bullet, measures
 them, renders them off-screen (OSMesa) and serves them live to a browser. This package holds
 the substep program, its benchmarks, the physics, render and lab libraries with their headers,
 a CMake package and pkg-config files.")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "substep developers <substep@localhost>")
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS ON)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "fonts-dejavu-core")
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "ffmpeg, gnuplot-nox, libeigen3-dev, libfcl-dev, nlohmann-json3-dev, libstb-dev, pkg-config")
include(CPack)
