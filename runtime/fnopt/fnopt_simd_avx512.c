/* fnopt_simd_body.h for AVX-512 (flags from the file-name suffix). */
#define FNOPT_SIMD_NAME(x) x##_avx512
#define FNOPT_SIMD_TABLE fnopt__simd_avx512
#include "fnopt/fnopt_simd_body.h"
