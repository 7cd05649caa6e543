/* The AArch64 NEON kernel table: the shared body over 4-lane q-register vectors. */
#include "kernels/simd_neon.h"
#define WEFT_KTABLE weft__kernels_neon
#define WEFT_KTABLE_ISA WEFT_ISA_NEON
#include "kernels/kernels_body.h"
