/* int8 weight quantisation and packing, fp16 conversion, and the choice of int8 variant. */
#include "kernels/qkernels.h"
#include "cpu/cpu.h"

#include <math.h>
#include <string.h>

extern const weft_qkernels weft__qkernels_scalar;
extern const weft_qkernels weft__qkernels_generic;
#if defined(__x86_64__)
extern const weft_qkernels weft__qkernels_avx2;
extern const weft_qkernels weft__qkernels_avxvnni;
extern const weft_qkernels weft__qkernels_avx512;
#endif
#if defined(__aarch64__)
extern const weft_qkernels weft__qkernels_neon;
#endif

static bool q8_all_finite(const float *x, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        if (!isfinite(x[i])) {
            return false;
        }
    }
    return true;
}

bool weft_q8_quantize_weights(const float *W, uint32_t N, uint32_t K, int8_t *Wq, float *scale)
{
    if (!q8_all_finite(W, (size_t)N * K)) {
        return false;
    }
    for (uint32_t n = 0; n < N; ++n) {
        const float *w = W + (size_t)n * K;
        float amax = 0.0f;
        for (uint32_t k = 0; k < K; ++k) {
            amax = fmaxf(amax, fabsf(w[k]));
        }
        scale[n] = amax / 127.0f;
        float inv = amax > 0.0f ? 127.0f / amax : 0.0f;
        for (uint32_t k = 0; k < K; ++k) {
            float q = nearbyintf(w[k] * inv); /* default rounding: to nearest, ties to even */
            q = fminf(fmaxf(q, -127.0f), 127.0f);
            Wq[(size_t)n * K + k] = (int8_t)(int)q;
        }
    }
    return true;
}

void weft_q8_pack(const int8_t *Wq, const float *scale, uint32_t N, uint32_t K, int8_t *packed, float *scale_out,
                  int32_t *wsum)
{
    uint32_t Np = weft_q8_pad_n(N), Kp = weft_q8_pad_k(K);
    memset(packed, 0, (size_t)Np * Kp);
    for (uint32_t c = 0; c < Np; ++c) {
        int32_t sum = 0;
        size_t block = c / WEFT_Q8_NB, lane = c % WEFT_Q8_NB;
        for (uint32_t k = 0; c < N && k < K; ++k) {
            int8_t w = Wq[(size_t)c * K + k];
            packed[block * WEFT_Q8_NB * Kp + (k / WEFT_Q8_KB) * WEFT_Q8_NB * WEFT_Q8_KB + lane * WEFT_Q8_KB +
                   k % WEFT_Q8_KB] = w;
            sum += w;
        }
        scale_out[c] = c < N ? scale[c] : 0.0f;
        wsum[c] = sum;
    }
}

uint16_t weft_f32_to_f16(float x)
{
    uint32_t f;
    memcpy(&f, &x, 4);
    uint32_t sign = (f >> 16) & 0x8000u;
    uint32_t absf = f & 0x7fffffffu;
    if (absf >= 0x7f800000u) { /* inf or NaN (keep a quiet NaN payload bit) */
        return (uint16_t)(sign | 0x7c00u | (absf > 0x7f800000u ? 0x0200u : 0u));
    }
    if (absf >= 0x477ff000u) { /* rounds to >= 65520: overflow to inf */
        return (uint16_t)(sign | 0x7c00u);
    }
    if (absf < 0x38800000u) { /* below the smallest normal half: subnormal or zero */
        if (absf < 0x33000000u) { /* < 2^-25: rounds to zero */
            return (uint16_t)sign;
        }
        uint32_t mant = (absf & 0x007fffffu) | 0x00800000u;
        int shift = 126 - (int)(absf >> 23); /* 14..24 */
        uint32_t half = mant >> shift;
        uint32_t rem = mant & ((1u << shift) - 1u);
        uint32_t mid = 1u << (shift - 1);
        if (rem > mid || (rem == mid && (half & 1u))) {
            half++;
        }
        return (uint16_t)(sign | half);
    }
    uint32_t h = ((absf >> 13) - (112u << 10)); /* rebias exponent 127 -> 15 */
    uint32_t rem = absf & 0x1fffu;
    if (rem > 0x1000u || (rem == 0x1000u && (h & 1u))) {
        h++;
    }
    return (uint16_t)(sign | h);
}

float weft_f16_to_f32(uint16_t h)
{
    uint32_t sign = (uint32_t)(h & 0x8000u) << 16;
    uint32_t exp = (h >> 10) & 0x1fu;
    uint32_t mant = h & 0x3ffu;
    uint32_t f;
    if (exp == 0x1fu) {
        f = sign | 0x7f800000u | (mant << 13);
    } else if (exp != 0) {
        f = sign | ((exp + 112u) << 23) | (mant << 13);
    } else if (mant == 0) {
        f = sign;
    } else { /* subnormal half: normalise */
        int e = -1;
        do {
            e++;
            mant <<= 1;
        } while (!(mant & 0x400u));
        f = sign | ((uint32_t)(112 - e) << 23) | ((mant & 0x3ffu) << 13);
    }
    float x;
    memcpy(&x, &f, 4);
    return x;
}

uint32_t weft_qkernels_variants(const weft_qkernels **out, uint32_t capacity)
{
    const weft_qkernels *all[6];
    uint32_t n = 0;
    all[n++] = &weft__qkernels_scalar;
    all[n++] = &weft__qkernels_generic;
    const weft_cpu_features *f = weft_cpu_features_get();
#if defined(__x86_64__)
    if (f->avx2 && f->fma && f->f16c) {
        all[n++] = &weft__qkernels_avx2;
        if (f->avxvnni) {
            all[n++] = &weft__qkernels_avxvnni;
        }
    }
    if (f->avx512f && f->avx512bw && f->avx512vl && f->avx512vnni && f->f16c) {
        all[n++] = &weft__qkernels_avx512;
    }
#endif
#if defined(__aarch64__)
    if (f->neon && f->asimddp && f->fp16) {
        all[n++] = &weft__qkernels_neon;
    }
#endif
    (void)f;
    uint32_t k = n < capacity ? n : capacity;
    memcpy(out, all, k * sizeof *out);
    return n;
}

const weft_qkernels *weft_qkernels_for_isa(weft_isa isa)
{
    if (!weft_cpu_isa_supported(isa)) {
        return NULL;
    }
    const weft_cpu_features *f = weft_cpu_features_get();
    (void)f;
    switch (isa) {
    case WEFT_ISA_SCALAR:
        return &weft__qkernels_scalar;
#if defined(__x86_64__)
    case WEFT_ISA_AVX2:
        return f->avxvnni ? &weft__qkernels_avxvnni : &weft__qkernels_avx2;
    case WEFT_ISA_AVX512:
        /* AVX-512 without VNNI (Skylake-X) does int8 best with the ymm sign trick. */
        if (f->avx512vnni) {
            return &weft__qkernels_avx512;
        }
        return f->avxvnni ? &weft__qkernels_avxvnni : &weft__qkernels_avx2;
#endif
#if defined(__aarch64__)
    case WEFT_ISA_NEON:
        return f->asimddp && f->fp16 ? &weft__qkernels_neon : &weft__qkernels_scalar;
#endif
    default:
        return NULL;
    }
}
