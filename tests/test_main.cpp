// Catch2 v2 only: its main. Catch2 v3 links its own (Catch2::Catch2WithMain, tests/CMakeLists.txt).
#define CATCH_CONFIG_MAIN
#include <catch2/catch.hpp>
