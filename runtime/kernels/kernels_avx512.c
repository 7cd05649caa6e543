/* The AVX-512 kernel table: the shared body over 16-lane zmm vectors with opmask tails. */
#include "kernels/simd_avx512.h"
#define WEFT_KTABLE weft__kernels_avx512
#define WEFT_KTABLE_ISA WEFT_ISA_AVX512
#include "kernels/kernels_body.h"
