// mpm: the command-line program. Every command lives in the library (engine/cli/cli.cpp).
#include "engine/cli/cli.h"

int main(int argc, char** argv) { return mpm::run_cli(argc, argv); }
