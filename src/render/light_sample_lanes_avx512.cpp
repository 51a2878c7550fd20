// The AVX-512 build of light_sample_lanes.cpp (compiled with -mavx512f -mavx512dq -mavx512vl; see
// src/CMakeLists.txt).
#define RT_LIGHT_SAMPLE_LANES_AVX512 1
#include "light_sample_lanes.cpp"
