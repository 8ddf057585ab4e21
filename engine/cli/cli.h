#pragma once
/// \file The `mpm` command line: flag parsing and one handler per command (run, validate,
/// golden, materials, preview, study, bench, compare). apps/mpm.cpp only calls run_cli.

namespace mpm {

/// Runs the command `argv` names and returns the process exit code (see kUsage in cli.cpp).
/// Bad usage prints a message to stderr and exits with kExitBadInput.
int run_cli(int argc, char** argv);

}  // namespace mpm
