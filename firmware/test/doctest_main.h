// The one main() of every native test suite. Include from exactly one .cpp per suite.
// Under `pio test` (PIO_UNIT_TESTING) PlatformIO needs every success reported and the exit
// code left to it; under CMake/ctest the exit code says pass or fail.
#pragma once
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest.h>

int main(int argc, char** argv) {
  doctest::Context context;
#ifdef PIO_UNIT_TESTING
  context.setOption("success", true);
  context.setOption("no-exitcode", true);
#endif
  context.applyCommandLine(argc, argv);
  return context.run();
}
