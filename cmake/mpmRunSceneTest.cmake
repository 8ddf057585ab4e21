# Runs one scene regression test; added by mpm_add_scene_test (mpmSceneTest.cmake) as
#
#   cmake -DMPM=<mpm> -DSCENE=<scene.yaml> -DGOLDEN=<summary.yaml> -DOUT=<folder>
#         [-DFRAMES=<n>] [-DTOL=<quantity>=<value>,...] -P mpmRunSceneTest.cmake
#
# 1. mpm run SCENE [--frames n] --out OUT --force --quiet   (must exit 0)
# 2. mpm compare OUT GOLDEN [--tol q=v ...]                  (0 pass, 1 beyond tolerance, 2 bad input)
cmake_minimum_required(VERSION 3.16)

# Prints its arguments joined, as they are (FATAL_ERROR would re-wrap the text and break the
# command lines it holds), then fails the test.
function(fail)
  set(text "")
  math(EXPR last "${ARGC} - 1")
  foreach(i RANGE ${last})
    string(APPEND text "${ARGV${i}}")
  endforeach()
  message(NOTICE "\nmpm scene test FAILED: ${text}\n")
  message(FATAL_ERROR "scene test failed (see above)")
endfunction()

foreach(var MPM SCENE GOLDEN OUT)
  if(NOT DEFINED ${var} OR "${${var}}" STREQUAL "")
    message(FATAL_ERROR "mpmRunSceneTest.cmake: -D${var}=... is required")
  endif()
endforeach()

if(FRAMES)
  set(frames_args --frames "${FRAMES}")
  set(frames_hint " --frames ${FRAMES}")
else()
  set(frames_args "")
  set(frames_hint "")
endif()
set(golden_cmd "mpm golden ${SCENE}${frames_hint} -o ${GOLDEN}")
# mpm golden refuses to replace a golden without --force.
set(regolden_cmd "${golden_cmd} --force")

if(NOT EXISTS "${GOLDEN}")
  fail("no golden summary ${GOLDEN}: make one with: ${golden_cmd}\n"
       "(the mpm program used here is ${MPM})")
endif()

set(tol_args "")
if(TOL)
  string(REPLACE "," ";" tol_items "${TOL}")
  foreach(item IN LISTS tol_items)
    list(APPEND tol_args --tol "${item}")
  endforeach()
endif()

# 1. Run the scene.
set(run_cmd "${MPM}" run "${SCENE}" ${frames_args} --out "${OUT}" --force --quiet)
string(REPLACE ";" " " run_text "${run_cmd}")
message(STATUS "${run_text}")
execute_process(COMMAND ${run_cmd} RESULT_VARIABLE run_rc)
if(NOT run_rc STREQUAL "0")
  fail("the scene did not run (mpm run exited with '${run_rc}'): ${run_text}\n"
       "See the messages above and ${OUT}/report.yaml.")
endif()

# 2. Compare its summary with the golden one.
set(compare_cmd "${MPM}" compare "${OUT}" "${GOLDEN}" ${tol_args})
string(REPLACE ";" " " compare_text "${compare_cmd}")
message(STATUS "${compare_text}")
execute_process(COMMAND ${compare_cmd} RESULT_VARIABLE compare_rc)
if(compare_rc STREQUAL "0")
  message(STATUS "within tolerance of ${GOLDEN}")
elseif(compare_rc STREQUAL "1")
  fail("the run differs from the golden summary beyond tolerance (table above).\n"
       "If the change is intended, check it (docs/regression-testing.md, \"Before accepting "
       "a changed golden\") and then regenerate the golden with: ${regolden_cmd}")
elseif(compare_rc STREQUAL "2")
  fail("the run cannot be compared with ${GOLDEN} (message above): the frame count, object "
       "names or particle counts differ, or a file is unreadable. If the scene was changed on "
       "purpose, regenerate the golden with: ${regolden_cmd}")
else()
  fail("mpm compare failed (exit '${compare_rc}'): ${compare_text}")
endif()
