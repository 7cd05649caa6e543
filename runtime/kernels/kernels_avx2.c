/* The AVX2 + FMA kernel table: the shared body over 8-lane ymm vectors. */
#include "kernels/simd_avx2.h"
#define WEFT_KTABLE weft__kernels_avx2
#define WEFT_KTABLE_ISA WEFT_ISA_AVX2
#include "kernels/kernels_body.h"
