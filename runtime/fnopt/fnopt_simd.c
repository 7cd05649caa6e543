/* fnopt_simd_body.h for the baseline instruction set of the build (SSE2 on x86-64, NEON on AArch64). */
#define FNOPT_SIMD_NAME(x) x##_generic
#define FNOPT_SIMD_TABLE fnopt__simd_generic
#include "fnopt/fnopt_simd_body.h"
