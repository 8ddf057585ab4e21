// mpm: the command-line program. Every command lives in the library (engine/run/cli.cpp).
#include "engine/run/cli.h"

int main(int argc, char** argv) { return mpm::run_cli(argc, argv); }
