# mpm_add_material_tests: the engine's generic material checks as a CTest test, run on the
# materials a plugin registers.
#
#   mpm_add_material_tests(TARGET <plugin target> [MATERIALS <name> ...] [NAME <test name>])
#
# The test runs `mpm_material_check <the plugin's file> [<name> ...]` (installed beside mpm,
# imported as mpm::material_check): zero stress at rest and under rotation, P = dpsi/dF by
# central differences, frame indifference and isotropy, finite results for nearly singular and
# inverted F (for materials that declare supports_inversion), and a positive wave speed that
# grows with stiffness. Without MATERIALS it checks every material the plugin registers. NAME
# defaults to "<target>: generic material checks". Calls enable_testing(); build, then `ctest`.
# See docs/materials.md.
include_guard(GLOBAL)

# A macro, so that enable_testing() acts on the caller's folder (in a function it would not).
macro(mpm_add_material_tests)
  enable_testing()
  _mpm_add_material_tests(${ARGN})
endmacro()

function(_mpm_add_material_tests)
  cmake_parse_arguments(PARSE_ARGV 0 ARG "" "TARGET;NAME" "MATERIALS")
  if(ARG_UNPARSED_ARGUMENTS OR NOT ARG_TARGET)
    message(FATAL_ERROR "usage: mpm_add_material_tests(TARGET plugin [MATERIALS name ...] "
                        "[NAME test])")
  endif()
  if(NOT TARGET ${ARG_TARGET})
    message(FATAL_ERROR "mpm_add_material_tests: '${ARG_TARGET}' is not a target (define the "
                        "plugin with add_library(${ARG_TARGET} MODULE ...) first)")
  endif()
  if(NOT ARG_NAME)
    set(ARG_NAME "${ARG_TARGET}: generic material checks")
  endif()
  add_test(NAME "${ARG_NAME}"
           COMMAND $<TARGET_FILE:mpm::material_check> $<TARGET_FILE:${ARG_TARGET}>
                   ${ARG_MATERIALS})
endfunction()
