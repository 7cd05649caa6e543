/* The shared body over one-lane plain C vectors (see simd_scalar.h). Not a dispatch level:
 * tests run it against the oracle so the body is checked on every target. */
#include "kernels/simd_scalar.h"
#define WEFT_KTABLE weft__kernels_generic
#include "kernels/kernels_body.h"
