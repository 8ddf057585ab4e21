# mpm_add_scene_test: a CTest regression test for a scene, against a golden run summary.
#
#   mpm_add_scene_test(NAME <name> SCENE <scene.yaml> GOLDEN <summary.yaml>
#                      [FRAMES <n>] [TOL <quantity>=<value> ...] [MPM <path to mpm>])
#
# The test runs
#   mpm run <scene> --frames <n> --out <build dir>/mpm_scene_tests/<name> --force --quiet
#   mpm compare <that folder> <golden> [--tol <quantity>=<value> ...]
# and passes if the run succeeds and every quantity of its summary is within tolerance of the
# golden one. Relative SCENE and GOLDEN paths are taken from the current source folder. Without
# FRAMES the scene's own simulation.frames is used. MPM defaults to the imported target mpm::mpm
# (find_package(mpm)) or else the in-tree target mpm. The test carries the label "mpm_scene".
# See docs/regression-testing.md.
include_guard(GLOBAL)

# Where the runner script is, captured at include time (fallback for CMake < 3.17).
set(_MPM_SCENE_TEST_DIR "${CMAKE_CURRENT_LIST_DIR}" CACHE INTERNAL "folder of mpmSceneTest.cmake")

function(mpm_add_scene_test)
  cmake_parse_arguments(PARSE_ARGV 0 ARG "" "NAME;SCENE;GOLDEN;FRAMES;MPM" "TOL")
  if(ARG_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "mpm_add_scene_test: unexpected arguments: ${ARG_UNPARSED_ARGUMENTS}\n"
                        "usage: mpm_add_scene_test(NAME name SCENE scene.yaml GOLDEN summary.yaml"
                        " [FRAMES n] [TOL quantity=value ...] [MPM path])")
  endif()
  foreach(required NAME SCENE GOLDEN)
    if(NOT ARG_${required})
      message(FATAL_ERROR "mpm_add_scene_test: ${required} is required")
    endif()
  endforeach()
  if(NOT ARG_NAME MATCHES "^[A-Za-z0-9_.+-]+$")
    message(FATAL_ERROR "mpm_add_scene_test: NAME '${ARG_NAME}' may use only letters, digits "
                        "and _ . + - (it names a folder)")
  endif()
  if(DEFINED ARG_FRAMES AND NOT ARG_FRAMES MATCHES "^[1-9][0-9]*$")
    message(FATAL_ERROR "mpm_add_scene_test(${ARG_NAME}): FRAMES must be a whole number >= 1, "
                        "got '${ARG_FRAMES}'")
  endif()
  foreach(item IN LISTS ARG_TOL)
    if(NOT item MATCHES "^[a-z_]+=[0-9.eE+-]+$")
      message(FATAL_ERROR "mpm_add_scene_test(${ARG_NAME}): TOL items are quantity=value, e.g. "
                          "centroid=1e-4; got '${item}'")
    endif()
  endforeach()

  get_filename_component(scene "${ARG_SCENE}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_SOURCE_DIR}")
  get_filename_component(golden "${ARG_GOLDEN}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_SOURCE_DIR}")
  if(NOT EXISTS "${scene}")
    message(FATAL_ERROR "mpm_add_scene_test(${ARG_NAME}): no scene file ${scene}")
  endif()

  if(ARG_MPM)
    set(mpm "${ARG_MPM}")
  elseif(TARGET mpm::mpm)
    set(mpm "$<TARGET_FILE:mpm::mpm>")
  elseif(TARGET mpm)
    set(mpm "$<TARGET_FILE:mpm>")
  else()
    message(FATAL_ERROR "mpm_add_scene_test(${ARG_NAME}): no mpm program: call "
                        "find_package(mpm REQUIRED) first, or pass MPM /path/to/mpm")
  endif()

  if(CMAKE_CURRENT_FUNCTION_LIST_DIR)
    set(script "${CMAKE_CURRENT_FUNCTION_LIST_DIR}/mpmRunSceneTest.cmake")
  else()
    set(script "${_MPM_SCENE_TEST_DIR}/mpmRunSceneTest.cmake")
  endif()

  # A list would become several arguments of add_test: pass the items joined by commas.
  string(REPLACE ";" "," tol "${ARG_TOL}")
  add_test(NAME "${ARG_NAME}"
           COMMAND "${CMAKE_COMMAND}"
                   "-DMPM=${mpm}"
                   "-DSCENE=${scene}"
                   "-DGOLDEN=${golden}"
                   "-DOUT=${CMAKE_CURRENT_BINARY_DIR}/mpm_scene_tests/${ARG_NAME}"
                   "-DFRAMES=${ARG_FRAMES}"
                   "-DTOL=${tol}"
                   -P "${script}")
  set_tests_properties("${ARG_NAME}" PROPERTIES LABELS mpm_scene)
endfunction()
