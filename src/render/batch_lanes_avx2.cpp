// The AVX2 build of batch_lanes.cpp (compiled with -mavx2; see src/CMakeLists.txt).
#define RT_BATCH_LANES_AVX2 1
#include "batch_lanes.cpp"
