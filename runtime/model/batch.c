/* weft_garments_step: many garments in one call. Garments of method MODEL that share context,
 * model and precision are stepped as one group (runtime/model/transformer.c stacks their
 * temporal transformers); every other garment goes through weft_garment_step. The per-garment
 * tail (NaN check, tethers, CCD post-process, buffer rotation) is weft__garment_finish_step
 * (runtime/garment/garment.c), applied to each member of a group. */
#include "ccd/ccd_internal.h"
#include "garment/garment.h"
#include "model/transformer.h"

#include <stdio.h>
#include <string.h>

typedef struct batch_status {
    weft_result first;
    uint32_t first_index;
    char message[400];
} batch_status;

/* Keeps the failure of the lowest index (groups are stepped when their first member comes up,
 * so failures do not arrive in array order). */
static void note(batch_status *st, uint32_t index, weft_result r)
{
    if (r != WEFT_OK && (st->first == WEFT_OK || index < st->first_index)) {
        st->first = r;
        st->first_index = index;
        snprintf(st->message, sizeof st->message, "%s", weft_last_error());
    }
}

/* What weft_garment_step does after the method's step succeeded. */
static weft_result finish(weft_garment *g, weft_result r, double forward_ms)
{
    if (r != WEFT_OK) {
        return r;
    }
    const double t0 = weft__now_ms();
    r = weft__garment_finish_step(g);
    if (r == WEFT_OK) {
        g->stats.method_ms = forward_ms;
        g->stats.step_ms = forward_ms + (weft__now_ms() - t0);
    }
    return r;
}

static void run_group(weft_garment *const *group, const uint32_t *index, uint32_t n, batch_status *st)
{
    weft_result results[WEFT_CT_GROUP_MAX];
    const double t0 = weft__now_ms();
    weft__ct_step_group(group, n, results);
    const double per = (weft__now_ms() - t0) / n; /* the shared forward pass, split evenly */
    for (uint32_t k = 0; k < n; ++k) {
        note(st, index[k], finish(group[k], results[k], per));
    }
}

static bool same_group(const weft_garment *a, const weft_garment *b)
{
    return a->ctx == b->ctx && a->model == b->model && a->precision == b->precision;
}

weft_result weft_garments_step(weft_garment *const *garments, uint32_t count)
{
    if (!garments || count == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garments_step: garments and a count >= 1 are required");
    }
    for (uint32_t i = 0; i < count; ++i) {
        if (!garments[i]) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garments_step: garments[%u] is NULL", i);
        }
        for (uint32_t j = 0; j < i; ++j) {
            if (garments[j] == garments[i]) {
                return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                                  "weft_garments_step: garments[%u] and garments[%u] are the same garment", j, i);
            }
        }
    }
    batch_status st = {WEFT_OK, 0, {0}};
    /* Cuts first (weft__garment_cut): a garment whose collider jumped is reset, not stepped. */
    for (uint32_t i = 0; i < count; ++i) {
        weft_garment *g = garments[i];
        g->cut_pending = false;
        if (g->collider_vertex_count > 0 && g->collider_next_set) {
            if (!weft__garment_enter(g, "weft_garments_step")) {
                g->cut_pending = true; /* not stepped this call */
                note(&st, i, WEFT_ERROR_BUSY);
                continue;
            }
            const double t0 = weft__now_ms();
            weft_result r;
            const bool cut = weft__garment_cut(g, &r);
            weft__garment_leave(g);
            if (cut) {
                g->cut_pending = true;
                if (r == WEFT_OK) {
                    g->stats.step_ms = weft__now_ms() - t0;
                }
                note(&st, i, r);
            }
        }
    }
    weft_garment *group[WEFT_CT_GROUP_MAX];
    uint32_t index[WEFT_CT_GROUP_MAX];
    for (uint32_t i = 0; i < count; ++i) {
        weft_garment *g = garments[i];
        if (g->cut_pending) {
            continue;
        }
        if (!weft__ct_batchable(g)) {
            note(&st, i, weft_garment_step(g));
            continue;
        }
        /* Garment i heads its group unless an earlier garment of the group already did. */
        bool led = false;
        for (uint32_t j = 0; j < i && !led; ++j) {
            led = !garments[j]->cut_pending && weft__ct_batchable(garments[j]) && same_group(garments[j], g);
        }
        if (led) {
            continue;
        }
        uint32_t n = 0;
        for (uint32_t j = i; j < count; ++j) {
            weft_garment *m = garments[j];
            if (m->cut_pending || !weft__ct_batchable(m) || !same_group(m, g)) {
                continue;
            }
            if (m->collider_vertex_count > 0 && !m->collider_next_set) {
                note(&st, j, weft_garment_step(m)); /* fails with its usual message, state kept */
                continue;
            }
            group[n] = m;
            index[n++] = j;
            if (n == WEFT_CT_GROUP_MAX) {
                run_group(group, index, n, &st);
                n = 0;
            }
        }
        if (n > 0) {
            run_group(group, index, n, &st);
        }
    }
    for (uint32_t i = 0; i < count; ++i) {
        garments[i]->cut_pending = false;
    }
    if (st.first != WEFT_OK) {
        return weft__fail(st.first, "weft_garments_step: garments[%u]: %s", st.first_index, st.message);
    }
    return WEFT_OK;
}
