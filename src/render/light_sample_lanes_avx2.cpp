// The AVX2 build of light_sample_lanes.cpp (compiled with -mavx2; see src/CMakeLists.txt).
#define RT_LIGHT_SAMPLE_LANES_AVX2 1
#include "light_sample_lanes.cpp"
