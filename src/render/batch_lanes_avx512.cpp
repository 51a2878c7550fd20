// The AVX-512 build of batch_lanes.cpp (compiled with -mavx512f -mavx512dq -mavx512vl; see
// src/CMakeLists.txt).
#define RT_BATCH_LANES_AVX512 1
#include "batch_lanes.cpp"
