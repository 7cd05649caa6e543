/* fnopt_simd_body.h for AVX2 + FMA (flags from the file-name suffix). */
#define FNOPT_SIMD_NAME(x) x##_avx2
#define FNOPT_SIMD_TABLE fnopt__simd_avx2
#include "fnopt/fnopt_simd_body.h"
