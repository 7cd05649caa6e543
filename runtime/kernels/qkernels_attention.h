/* One block width of the deterministic attention (qkernels_body.h includes it once per width).
 * The includer defines QK_QB (queries per block: 16 or 32, a multiple of the vector width VW) and
 * QK_ATT(name), which names this width's functions; both are undefined at the end.
 *
 * Lanes run along a block of QK_QB queries (QK_QV vectors), so every score, the softmax of every
 * query and every output are the per-query chains of the composed form (see qkernels.h):
 *   pass 1: S[j][l] = (Q K^T chain) * scale for JB keys at a time (independent chains);
 *   pass 2: e = qk_exp(S - max), summed into 16 partials by key index mod 16, the canonical tree;
 *   pass 3: out = sum_j (e_j * inv) V[j], d in register chunks of a compile-time width.
 * S (nk x QK_QB floats) is the only large scratch. The block width changes no result. */
#if !defined(QK_QB) || !defined(QK_ATT)
#error "define QK_QB and QK_ATT before including qkernels_attention.h"
#endif
#if QK_QB > 32 || QK_QB % 16 != 0
#error "attention_det blocks are 16 or 32 queries (WEFT_QK_ATT_QB sizes the scratch for 32)"
#endif
#define QK_QV (QK_QB / VW)
#define QK_ATT_JB (8 / QK_QV > 0 ? 8 / QK_QV : 1)

static void QK_ATT(att_scores)(const float *qt, const float *K, uint32_t ldk, uint32_t nk, uint32_t dh, float scale,
                       float *S, V *mx)
{
    const V vs = v_set1(scale);
    V m[QK_QV];
    for (int v = 0; v < QK_QV; ++v) {
        m[v] = v_set1(-INFINITY);
    }
    uint32_t j = 0;
    for (; j + QK_ATT_JB <= nk; j += QK_ATT_JB) {
        V acc[QK_ATT_JB][QK_QV];
        QK_UNROLL for (int b = 0; b < QK_ATT_JB; ++b)
        {
            QK_UNROLL for (int v = 0; v < QK_QV; ++v) { acc[b][v] = v_zero(); }
        }
        const float *k0 = K + (size_t)j * ldk;
        for (uint32_t d = 0; d < dh; ++d) {
            V q[QK_QV];
            QK_UNROLL for (int v = 0; v < QK_QV; ++v) { q[v] = v_load(qt + (size_t)d * QK_QB + v * VW); }
            QK_UNROLL for (int b = 0; b < QK_ATT_JB; ++b)
            {
                const V kv = v_set1(k0[(size_t)b * ldk + d]);
                QK_UNROLL for (int v = 0; v < QK_QV; ++v) { acc[b][v] = v_fma(q[v], kv, acc[b][v]); }
            }
        }
        QK_UNROLL for (int b = 0; b < QK_ATT_JB; ++b)
        {
            QK_UNROLL for (int v = 0; v < QK_QV; ++v)
            {
                const V sv = v_mul(acc[b][v], vs);
                v_store(S + (size_t)(j + (uint32_t)b) * QK_QB + v * VW, sv);
                m[v] = qk_max_ordered(m[v], sv);
            }
        }
    }
    for (; j < nk; ++j) {
        V acc[QK_QV];
        QK_UNROLL for (int v = 0; v < QK_QV; ++v) { acc[v] = v_zero(); }
        const float *k0 = K + (size_t)j * ldk;
        for (uint32_t d = 0; d < dh; ++d) {
            const V kv = v_set1(k0[d]);
            QK_UNROLL for (int v = 0; v < QK_QV; ++v)
            {
                acc[v] = v_fma(v_load(qt + (size_t)d * QK_QB + v * VW), kv, acc[v]);
            }
        }
        QK_UNROLL for (int v = 0; v < QK_QV; ++v)
        {
            const V sv = v_mul(acc[v], vs);
            v_store(S + (size_t)j * QK_QB + v * VW, sv);
            m[v] = qk_max_ordered(m[v], sv);
        }
    }
    for (int v = 0; v < QK_QV; ++v) {
        mx[v] = m[v];
    }
}

/* e = exp(S - max) in place; returns 1 / sum per lane (0 for a fully masked query). */
static void QK_ATT(att_softmax)(float *S, uint32_t nk, const V *m, V *inv)
{
    V part[16][QK_QV];
    VM dead[QK_QV];
    for (int v = 0; v < QK_QV; ++v) {
        dead[v] = m_eq(m[v], v_set1(-INFINITY));
        for (int u = 0; u < 16; ++u) {
            part[u][v] = v_zero();
        }
    }
    uint32_t j = 0;
    for (; j + 16 <= nk; j += 16) {
        QK_UNROLL for (int u = 0; u < 16; ++u)
        {
            float *s = S + (size_t)(j + (uint32_t)u) * QK_QB;
            QK_UNROLL for (int v = 0; v < QK_QV; ++v)
            {
                const V e = v_sel(dead[v], v_zero(), qk_exp(v_sub(v_load(s + v * VW), m[v])));
                v_store(s + v * VW, e);
                part[u][v] = v_add(part[u][v], e);
            }
        }
    }
    for (int u = 0; j < nk; ++j, ++u) {
        float *s = S + (size_t)j * QK_QB;
        for (int v = 0; v < QK_QV; ++v) {
            const V e = v_sel(dead[v], v_zero(), qk_exp(v_sub(v_load(s + v * VW), m[v])));
            v_store(s + v * VW, e);
            part[u][v] = v_add(part[u][v], e);
        }
    }
    for (int w = 8; w >= 1; w /= 2) {
        for (int u = 0; u < w; ++u) {
            for (int v = 0; v < QK_QV; ++v) {
                part[u][v] = v_add(part[u][v], part[u + w][v]);
            }
        }
    }
    for (int v = 0; v < QK_QV; ++v) {
        inv[v] = v_sel(dead[v], v_zero(), v_div(v_set1(1.0f), part[0][v]));
    }
}

/* stage[dd][l] = sum_j (e[j][l] * inv) V[j][dd] for DC columns of V, keys in order. */
#define QK_ATT_PV(DC)                                                                                   \
    static void QK_ATT(att_pv_##DC)(const float *S, const V *inv, const float *Vm, uint32_t ldv, uint32_t nk,    \
                            float *stage)                                                               \
    {                                                                                                   \
        V acc[DC][QK_QV];                                                                               \
        QK_UNROLL for (int d = 0; d < (DC); ++d)                                                        \
        {                                                                                               \
            QK_UNROLL for (int v = 0; v < QK_QV; ++v) { acc[d][v] = v_zero(); }                         \
        }                                                                                               \
        for (uint32_t j = 0; j < nk; ++j) {                                                             \
            V p[QK_QV];                                                                                 \
            QK_UNROLL for (int v = 0; v < QK_QV; ++v) { p[v] = v_mul(v_load(S + (size_t)j * QK_QB + v * VW), inv[v]); } \
            const float *vr = Vm + (size_t)j * ldv;                                                     \
            QK_UNROLL for (int d = 0; d < (DC); ++d)                                                    \
            {                                                                                           \
                const V vv = v_set1(vr[d]);                                                             \
                QK_UNROLL for (int v = 0; v < QK_QV; ++v) { acc[d][v] = v_fma(p[v], vv, acc[d][v]); }   \
            }                                                                                           \
        }                                                                                               \
        for (int d = 0; d < (DC); ++d) {                                                                \
            for (int v = 0; v < QK_QV; ++v) {                                                           \
                v_store(stage + (size_t)d * QK_QB + v * VW, acc[d][v]);                                    \
            }                                                                                           \
        }                                                                                               \
    }

QK_ATT_PV(24)
QK_ATT_PV(12)
QK_ATT_PV(8)
QK_ATT_PV(6)
QK_ATT_PV(4)
QK_ATT_PV(2)
QK_ATT_PV(1)

/* The widest chunk that fits the accumulator budget and what is left of the head. */
static uint32_t QK_ATT(att_pv)(const float *S, const V *inv, const float *Vm, uint32_t ldv, uint32_t nk, uint32_t left,
                       float *stage)
{
    const uint32_t cap = QK_ATT_ACC / QK_QV > 0 ? QK_ATT_ACC / QK_QV : 1;
    if (cap >= 24 && left >= 24) {
        QK_ATT(att_pv_24)(S, inv, Vm, ldv, nk, stage);
        return 24;
    }
    if (cap >= 12 && left >= 12) {
        QK_ATT(att_pv_12)(S, inv, Vm, ldv, nk, stage);
        return 12;
    }
    if (cap >= 8 && left >= 8) {
        QK_ATT(att_pv_8)(S, inv, Vm, ldv, nk, stage);
        return 8;
    }
    if (cap >= 6 && left >= 6) {
        QK_ATT(att_pv_6)(S, inv, Vm, ldv, nk, stage);
        return 6;
    }
    if (cap >= 4 && left >= 4) {
        QK_ATT(att_pv_4)(S, inv, Vm, ldv, nk, stage);
        return 4;
    }
    if (cap >= 2 && left >= 2) {
        QK_ATT(att_pv_2)(S, inv, Vm, ldv, nk, stage);
        return 2;
    }
    QK_ATT(att_pv_1)(S, inv, Vm, ldv, nk, stage);
    return 1;
}

static void QK_ATT(attention_det)(const float *Q, uint32_t ldq, const float *K, uint32_t ldk, const float *Vm, uint32_t ldv,
                          uint32_t nq, uint32_t nk, uint32_t H, uint32_t dh, float scale, const uint8_t *mask,
                          const float *key_bias, float *out, uint32_t ldo, float *scratch)
{
    float *S = scratch, *qt = S + (size_t)nk * QK_QB, *stage = qt + (size_t)dh * QK_QB;
    for (uint32_t h = 0; h < H; ++h) {
        const size_t hc = (size_t)h * dh;
        for (uint32_t i0 = 0; i0 < nq; i0 += QK_QB) {
            const uint32_t nl = nq - i0 < QK_QB ? nq - i0 : QK_QB;
            for (uint32_t d = 0; d < dh; ++d) { /* the block's queries, transposed; idle lanes 0 */
                for (uint32_t l = 0; l < QK_QB; ++l) {
                    qt[(size_t)d * QK_QB + l] = l < nl ? Q[(size_t)(i0 + l) * ldq + hc + d] : 0.0f;
                }
            }
            V m[QK_QV], inv[QK_QV];
            QK_ATT(att_scores)(qt, K + hc, ldk, nk, dh, scale, S, m);
            for (uint32_t j = 0; key_bias && j < nk; ++j) { /* every lane; idle ones are never read */
                const V b = v_set1(key_bias[j]);
                for (int v = 0; v < QK_QV; ++v) {
                    v_store(S + (size_t)j * QK_QB + v * VW, v_add(v_load(S + (size_t)j * QK_QB + v * VW), b));
                }
            }
            if (mask || key_bias) {
                for (uint32_t l = 0; mask && l < nl; ++l) {
                    const uint8_t *mr = mask + (size_t)(i0 + l) * nk;
                    for (uint32_t j = 0; j < nk; ++j) {
                        if (!mr[j]) {
                            S[(size_t)j * QK_QB + l] = -INFINITY;
                        }
                    }
                }
                for (int v = 0; v < QK_QV; ++v) {
                    m[v] = v_set1(-INFINITY);
                    for (uint32_t j = 0; j < nk; ++j) {
                        m[v] = qk_max_ordered(m[v], v_load(S + (size_t)j * QK_QB + v * VW));
                    }
                }
            }
            QK_ATT(att_softmax)(S, nk, m, inv);
            for (uint32_t d0 = 0; d0 < dh;) {
                const uint32_t dc = QK_ATT(att_pv)(S, inv, Vm + hc + d0, ldv, nk, dh - d0, stage);
                for (uint32_t l = 0; l < nl; ++l) {
                    float *o = out + (size_t)(i0 + l) * ldo + hc + d0;
                    for (uint32_t d = 0; d < dc; ++d) {
                        o[d] = stage[(size_t)d * QK_QB + l];
                    }
                }
                d0 += dc;
            }
        }
    }
}

#undef QK_ATT_PV
#undef QK_ATT_JB
#undef QK_QV
#undef QK_ATT
#undef QK_QB
