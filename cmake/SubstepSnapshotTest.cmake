# substep_add_snapshot_test(NAME name SCENE scene.json AT t [t...] GOLDEN dir
#                           [THRESHOLD levels] [MAX_SHARE share] [SETTINGS option...])
#
# A CTest test NAME that renders SCENE at each simulated time with `substep snapshot` and compares
# every frame with GOLDEN/<scene>@<t>.png (docs/snapshots.md); it fails on a mismatch and leaves
# <scene>@<t>.actual.png and <scene>@<t>.diff.png in snapshots/NAME/ of the current build folder.
# THRESHOLD (levels per channel, default 24) and MAX_SHARE (share of pixels, default 0.0002) set
# the tolerance; SETTINGS are more options of `substep snapshot` (--size 320x180, --algo a5, ...).
# SCENE and GOLDEN are relative to the current source folder. The target NAME_update rewrites
# that test's goldens, snapshot_update every test's (look at them before committing them).
function(substep_add_snapshot_test)
  cmake_parse_arguments(PARSE_ARGV 0 arg "" "NAME;SCENE;GOLDEN;THRESHOLD;MAX_SHARE" "AT;SETTINGS")
  foreach(required NAME SCENE AT GOLDEN)
    if(NOT arg_${required})
      message(FATAL_ERROR "substep_add_snapshot_test: ${required} is missing "
        "(usage: NAME name SCENE scene.json AT t... GOLDEN dir [THRESHOLD n] [MAX_SHARE x] [SETTINGS option...])")
    endif()
  endforeach()
  if(arg_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "substep_add_snapshot_test(${arg_NAME}): unknown arguments ${arg_UNPARSED_ARGUMENTS} "
      "(put options of substep snapshot after SETTINGS)")
  endif()
  get_filename_component(scene ${arg_SCENE} ABSOLUTE BASE_DIR ${CMAKE_CURRENT_SOURCE_DIR})
  get_filename_component(golden ${arg_GOLDEN} ABSOLUTE BASE_DIR ${CMAKE_CURRENT_SOURCE_DIR})
  if(NOT EXISTS ${scene})
    message(FATAL_ERROR "substep_add_snapshot_test(${arg_NAME}): no scene file ${scene}")
  endif()
  list(JOIN arg_AT "," at)  # AT 0.5 1.5 or AT 0.5,1.5
  set(args snapshot ${scene} --at ${at} --golden ${golden})
  if(DEFINED arg_THRESHOLD)
    list(APPEND args --threshold ${arg_THRESHOLD})
  endif()
  if(DEFINED arg_MAX_SHARE)
    list(APPEND args --max-share ${arg_MAX_SHARE})
  endif()
  list(APPEND args ${arg_SETTINGS})
  add_test(NAME ${arg_NAME}
    COMMAND $<TARGET_FILE:substep::substep> ${args} --out ${CMAKE_CURRENT_BINARY_DIR}/snapshots/${arg_NAME} -q)
  set_tests_properties(${arg_NAME} PROPERTIES LABELS snapshot)
  add_custom_target(${arg_NAME}_update COMMAND $<TARGET_FILE:substep::substep> ${args} --update VERBATIM)
  if(NOT TARGET snapshot_update)
    add_custom_target(snapshot_update)
  endif()
  add_dependencies(snapshot_update ${arg_NAME}_update)
endfunction()
