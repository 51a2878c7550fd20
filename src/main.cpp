#include "rt/app/cli.h"

int main(int argc, char** argv) { return rt::run_cli(argc, argv); }
