// The AVX2 build of triangle_clusters.cpp's kernel (compiled with -mavx2; see src/CMakeLists.txt).
#define RT_TRIANGLE_CLUSTERS_AVX2 1
#include "triangle_clusters.cpp"
