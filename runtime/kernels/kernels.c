/* Table lookup by level, and the attention scratch size every level fits in. */
#include "kernels/kernels.h"
#include "cpu/cpu.h"
#include "kernels/kernels_internal.h"

const weft_kernels *weft_kernels_for_isa(weft_isa isa)
{
    if (isa == WEFT_ISA_AUTO) {
        isa = weft_cpu_best_isa();
    }
    if (!weft_cpu_isa_supported(isa)) {
        return NULL;
    }
    switch (isa) {
    case WEFT_ISA_SCALAR:
        return &weft__kernels_scalar;
#if defined(__x86_64__)
    case WEFT_ISA_AVX2:
        return &weft__kernels_avx2;
    case WEFT_ISA_AVX512:
        return &weft__kernels_avx512;
#endif
#if defined(__aarch64__)
    case WEFT_ISA_NEON:
        return &weft__kernels_neon;
#endif
    default:
        return NULL;
    }
}

size_t weft_attention_scratch(uint32_t nq, uint32_t nk)
{
    /* score tile, running max and sum per query row, the head's transposed keys, alignment slack */
    const size_t qb = weft__attn_qb(nq);
    return qb * weft__attn_kbp(nk) + 2u * qb + (size_t)WEFT__ATTN_DB * weft__attn_pad(nk) + 32u;
}
