# cmake -DSOURCE=DIR -DBUILD=DIR -Dsubstep_DIR=DIR -P project_test.cmake
# Configures the CMake project SOURCE in BUILD (from scratch) against the substep package in
# substep_DIR, builds it and runs its CTest; fails when any step fails.
get_filename_component(bin ${CMAKE_COMMAND} DIRECTORY)
file(REMOVE_RECURSE ${BUILD})
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SOURCE} -B ${BUILD} -G Ninja -Dsubstep_DIR=${substep_DIR}
  COMMAND_ERROR_IS_FATAL ANY)
execute_process(COMMAND ${CMAKE_COMMAND} --build ${BUILD} COMMAND_ERROR_IS_FATAL ANY)
execute_process(COMMAND ${bin}/ctest --test-dir ${BUILD} --output-on-failure COMMAND_ERROR_IS_FATAL ANY)
