/* Untangling for the reference XPBD on real motion (weft__xpbd_set_untangle in xpbd.h).
 *
 * The bounded solver keeps every crossing it finds: a contact pushes a pair apart along the side
 * it is found on, and a vertex's bound shrinks with its distance to the triangle it went through,
 * so cloth that crossed cloth (where the body squeezed it between two of its parts) stays crossed.
 * This undoes such crossings history-free, by shortening the intersection contour (the idea of
 * intersection contour minimisation, Volino and Magnenat-Thalmann 2006), on the cloth the caller
 * marks:
 *
 *   - at the step's start, the marked vertices on a crossing (an edge through a triangle) are
 *     found; the solver drops the bounds and contacts between them;
 *   - each substep, an edge that crosses a triangle at point x has the contour's neighbours of x
 *     in the two triangles that share the edge (the other ends of the segments where each meets
 *     the triangle); x moving toward them shortens the contour, and x slides along the edge when
 *     the layers move apart along the triangle's normal, so the edge's end on their side goes
 *     back through the triangle. On a contour around a vertex that vertex goes back; on a straight
 *     stretch the neighbours cancel and nothing moves.
 */
#include "xpbd/xpbd.h"

#include <math.h>
#include <string.h>

#define FREE_ARR(ptr, count) weft__free(ctx, (ptr), (size_t)(count) * sizeof *(ptr))

weft_result xpbd_untangle_create(const weft_context *ctx, xpbd_untangle *u, uint32_t n, uint32_t ntri, uint32_t nedge)
{
    memset(u, 0, sizeof *u);
    u->n = n;
    u->ntri = ntri;
    u->nedge = nedge;
#define ALLOC_ARR(ptr, count) ((ptr) = weft__alloc(ctx, (size_t)(count) * sizeof *(ptr)))
    const bool ok = ALLOC_ARR(u->cand_tri, ntri + 1) && ALLOC_ARR(u->cand_edge, nedge + 1) &&
                    ALLOC_ARR(u->box, 6 * (size_t)ntri + 6) && ALLOC_ARR(u->crossing, n + 1);
#undef ALLOC_ARR
    if (!ok) {
        xpbd_untangle_destroy(ctx, u);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memset(u->crossing, 0, n);
    return WEFT_OK;
}

void xpbd_untangle_destroy(const weft_context *ctx, xpbd_untangle *u)
{
    FREE_ARR(u->cand_tri, u->ntri + 1);
    FREE_ARR(u->cand_edge, u->nedge + 1);
    FREE_ARR(u->box, 6 * (size_t)u->ntri + 6);
    FREE_ARR(u->crossing, u->n + 1);
    memset(u, 0, sizeof *u);
}

/* Segment p-q against triangle (a, b, c): whether it crosses the triangle's plane inside the
 * triangle; then the unit normal, the signed distances of p and q along it and the crossing's
 * barycentric weights. */
static bool segment_crosses(const double *p, const double *q, const double *a, const double *b, const double *c,
                            double n[3], double *dp, double *dq, double bary[3])
{
    double e1[3], e2[3];
    geo_sub(e1, b, a);
    geo_sub(e2, c, a);
    geo_cross(n, e1, e2);
    const double area2 = geo_len(n);
    if (!(area2 > 0.0)) {
        return false;
    }
    for (int k = 0; k < 3; ++k) {
        n[k] /= area2;
    }
    double ap[3], aq[3];
    geo_sub(ap, p, a);
    geo_sub(aq, q, a);
    const double sp = geo_dot(n, ap), sq = geo_dot(n, aq);
    if (!((sp < 0.0 && sq > 0.0) || (sp > 0.0 && sq < 0.0))) {
        return false;
    }
    const double t = sp / (sp - sq);
    double x[3], ra[3], rb[3], rc[3], cr[3];
    for (int k = 0; k < 3; ++k) {
        x[k] = p[k] + t * (q[k] - p[k]);
    }
    geo_sub(ra, a, x);
    geo_sub(rb, b, x);
    geo_sub(rc, c, x);
    geo_cross(cr, rb, rc);
    const double wa = geo_dot(cr, n);
    geo_cross(cr, rc, ra);
    const double wb = geo_dot(cr, n);
    geo_cross(cr, ra, rb);
    const double wc = geo_dot(cr, n);
    if (wa < 0.0 || wb < 0.0 || wc < 0.0) {
        return false;
    }
    bary[0] = wa / area2;
    bary[1] = wb / area2;
    bary[2] = wc / area2;
    *dp = sp;
    *dq = sq;
    return true;
}

static void candidate_boxes(xpbd_untangle *u, const uint32_t *tris, const double *x)
{
    for (uint32_t k = 0; k < u->ncand_tri; ++k) {
        const uint32_t *t = tris + 3 * (size_t)u->cand_tri[k];
        double *bx = u->box + 6 * (size_t)k;
        for (int a = 0; a < 3; ++a) {
            const double v0 = x[3 * (size_t)t[0] + a], v1 = x[3 * (size_t)t[1] + a], v2 = x[3 * (size_t)t[2] + a];
            bx[a] = fmin(v0, fmin(v1, v2));
            bx[3 + a] = fmax(v0, fmax(v1, v2));
        }
    }
}

static bool edge_meets_box(const double *p, const double *q, const double *bx)
{
    for (int a = 0; a < 3; ++a) {
        if (fmax(p[a], q[a]) < bx[a] || fmin(p[a], q[a]) > bx[3 + a]) {
            return false;
        }
    }
    return true;
}

/* The other end of the segment where triangles f and t meet, seen from x (a point of it): the
 * farthest of the points where an edge of one crosses the other. False when there is none apart
 * from x. */
static bool other_end(const double *x, const double *pos, const uint32_t *f, const uint32_t *t, double y[3])
{
    double best = 0.0;
    for (int side = 0; side < 2; ++side) {
        const uint32_t *e = side ? t : f, *o = side ? f : t;
        for (int k = 0; k < 3; ++k) {
            const double *p = pos + 3 * (size_t)e[k], *q = pos + 3 * (size_t)e[(k + 1) % 3];
            double nrm[3], dp, dq, bary[3], c[3];
            if (!segment_crosses(p, q, pos + 3 * (size_t)o[0], pos + 3 * (size_t)o[1], pos + 3 * (size_t)o[2], nrm, &dp,
                                 &dq, bary)) {
                continue;
            }
            const double s = dp / (dp - dq);
            for (int a = 0; a < 3; ++a) {
                c[a] = p[a] + s * (q[a] - p[a]) - x[a];
            }
            const double l = geo_len(c);
            if (l > best) {
                best = l;
                for (int a = 0; a < 3; ++a) {
                    y[a] = x[a] + c[a];
                }
            }
        }
    }
    return best > 0.0;
}

/* Edge e (p, q) crosses triangle t: which end goes back through t. The crossing point x slides
 * along e when the two layers move apart along t's normal; the contour's length falls fastest
 * toward its neighbours on the contour (the other ends of the segments where e's triangles meet
 * t), so the end on that side goes through. Returns 0 for p, 1 for q, -1 when undecided. */
static int end_to_move(const geo_topo *topo, const uint32_t *tris, uint32_t e, const uint32_t *t, const double *pos,
                       const double *x)
{
    const uint32_t *ed = topo->edges + 2 * (size_t)e;
    double g[3] = {0.0, 0.0, 0.0}, y[3], d[3];
    for (int k = 0; k < 2; ++k) {
        const uint32_t f = topo->edge_tri[2 * (size_t)e + k];
        if (f == UINT32_MAX || !other_end(x, pos, tris + 3 * (size_t)f, t, y)) {
            continue;
        }
        geo_sub(d, y, x);
        geo_axpy(g, 1.0 / geo_len(d), d);
    }
    geo_sub(d, pos + 3 * (size_t)ed[1], pos + 3 * (size_t)ed[0]);
    const double s = geo_dot(g, d);
    return s > 1e-9 * geo_len(d) ? 1 : s < -1e-9 * geo_len(d) ? 0 : -1;
}

/* Whether candidate edge i crosses candidate triangle k at x (an edge and a triangle that share a
 * vertex do not count); then the edge's and the triangle's vertices and segment_crosses' outputs.
 * The candidates' boxes must be those of x. */
static bool candidate_crosses(const xpbd_untangle *u, const geo_topo *topo, const uint32_t *tris, const double *x,
                              uint32_t i, uint32_t k, const uint32_t **edge, const uint32_t **tri, double nrm[3],
                              double *dp, double *dq, double bary[3])
{
    const uint32_t *ed = topo->edges + 2 * (size_t)u->cand_edge[i], *t = tris + 3 * (size_t)u->cand_tri[k];
    const double *p = x + 3 * (size_t)ed[0], *q = x + 3 * (size_t)ed[1];
    *edge = ed;
    *tri = t;
    return t[0] != ed[0] && t[1] != ed[0] && t[2] != ed[0] && t[0] != ed[1] && t[1] != ed[1] && t[2] != ed[1] &&
           edge_meets_box(p, q, u->box + 6 * (size_t)k) &&
           segment_crosses(p, q, x + 3 * (size_t)t[0], x + 3 * (size_t)t[1], x + 3 * (size_t)t[2], nrm, dp, dq, bary);
}

uint32_t xpbd_untangle_begin(xpbd_untangle *u, const geo_topo *topo, const uint32_t *tris, const uint8_t *mask,
                             const double *x)
{
    memset(u->crossing, 0, u->n);
    u->crossing_count = 0;
    u->mask = mask;
    u->ncand_tri = u->ncand_edge = 0;
    for (uint32_t t = 0; t < u->ntri; ++t) {
        const uint32_t *tr = tris + 3 * (size_t)t;
        if (mask[tr[0]] | mask[tr[1]] | mask[tr[2]]) {
            u->cand_tri[u->ncand_tri++] = t;
        }
    }
    for (uint32_t e = 0; e < u->nedge; ++e) {
        const uint32_t *ed = topo->edges + 2 * (size_t)e;
        if (mask[ed[0]] | mask[ed[1]]) {
            u->cand_edge[u->ncand_edge++] = e;
        }
    }
    if (u->ncand_tri == 0 || u->ncand_edge == 0) {
        return 0;
    }
    candidate_boxes(u, tris, x);
    for (uint32_t i = 0; i < u->ncand_edge; ++i) {
        for (uint32_t k = 0; k < u->ncand_tri; ++k) {
            const uint32_t *ed, *t;
            double nrm[3], dp, dq, bary[3];
            if (candidate_crosses(u, topo, tris, x, i, k, &ed, &t, nrm, &dp, &dq, bary)) {
                for (int j = 0; j < 3; ++j) {
                    u->crossing[t[j]] |= mask[t[j]];
                }
                u->crossing[ed[0]] |= mask[ed[0]];
                u->crossing[ed[1]] |= mask[ed[1]];
            }
        }
    }
    for (uint32_t i = 0; i < u->n; ++i) {
        u->crossing_count += u->crossing[i];
    }
    return u->crossing_count;
}

uint32_t xpbd_untangle_project(xpbd_untangle *u, const geo_topo *topo, const uint32_t *tris, double *x, const double *w,
                               double margin)
{
    if (u->crossing_count == 0) {
        return 0;
    }
    candidate_boxes(u, tris, x);
    uint32_t undone = 0;
    for (uint32_t i = 0; i < u->ncand_edge; ++i) {
        const uint32_t e = u->cand_edge[i];
        for (uint32_t k = 0; k < u->ncand_tri; ++k) {
            const uint32_t *ed, *t;
            double nrm[3], dp, dq, bary[3], at[3];
            if (!candidate_crosses(u, topo, tris, x, i, k, &ed, &t, nrm, &dp, &dq, bary)) {
                continue;
            }
            const double *p = x + 3 * (size_t)ed[0], *q = x + 3 * (size_t)ed[1];
            for (int a = 0; a < 3; ++a) {
                at[a] = p[a] + dp / (dp - dq) * (q[a] - p[a]);
            }
            const int end = end_to_move(topo, tris, e, t, x, at);
            if (end < 0) {
                continue;
            }
            const uint32_t mv = ed[end];
            const double dm = end ? dq : dp, dstay = end ? dp : dq;
            /* C = side (n . (x_mv - crossing)) - margin >= 0, side the staying end's: the moving
             * end goes along side n, the triangle's corners against it by their weights. Only
             * marked cloth moves (the caller does not certify it against itself). */
            const double wm = u->mask[mv] ? w[mv] : 0.0;
            const double wt[3] = {u->mask[t[0]] ? w[t[0]] : 0.0, u->mask[t[1]] ? w[t[1]] : 0.0,
                                  u->mask[t[2]] ? w[t[2]] : 0.0};
            const double side = dstay > 0.0 ? 1.0 : -1.0, c = side * dm - margin;
            const double denom = wm + bary[0] * bary[0] * wt[0] + bary[1] * bary[1] * wt[1] + bary[2] * bary[2] * wt[2];
            if (!(denom > 0.0) || !(c < 0.0)) {
                continue;
            }
            double dl = -c / denom;
            const double reach = fmax(wm, fmax(bary[0] * wt[0], fmax(bary[1] * wt[1], bary[2] * wt[2]))) * dl;
            if (reach > margin) {
                dl *= margin / reach;
            }
            for (int a = 0; a < 3; ++a) {
                const double m = side * dl * nrm[a];
                x[3 * (size_t)mv + a] += wm * m;
                for (int j = 0; j < 3; ++j) {
                    x[3 * (size_t)t[j] + a] -= wt[j] * bary[j] * m;
                }
            }
            undone++;
            /* the triangle's box is stale now; the next substep rebuilds it */
        }
    }
    return undone;
}
