// mpm: the command-line program. Every command lives in the library (engine/cli.cpp).
#include "engine/cli.h"

int main(int argc, char** argv) { return mpm::run_cli(argc, argv); }
