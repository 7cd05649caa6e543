/* XPBD cloth solver with small steps (one Gauss-Seidel pass per substep), GIPC-equivalent
 * energies, contact with thickness and Coulomb friction, and per-vertex conservative
 * displacement bounds that keep cloth-cloth and cloth-collider pairs from ever crossing.
 *
 * Substep (h = frame_dt / S):
 *   1. proximity detection at the substep start (every detect_interval substeps): contact
 *      candidates and per-vertex bounds b_v from the distance to every primitive in reach,
 *      reduced by how far kinematic geometry (collider, pins) can move before the next pass;
 *   2. predict x = x + h v + h^2 g; pins and collider move to their substep-end positions;
 *   3. membrane (BW warp/weft stretch, shear), signed-dihedral bending, contacts + friction;
 *   4. truncate every free vertex to its bound around the snapshot;
 *   5. v = (x - x_start) / h.
 * Everything is double precision; the garment's float buffers are read and written at the
 * frame boundary only, and the double state carries over between frames. */
#include "xpbd/xpbd.h"

#include <float.h>
#include <math.h>
#include <string.h>
#ifdef XPBD_DEBUG_BOUNDS
#include <stdio.h>
#endif

#define FRAME_DT (1.0 / 60.0)
#define XPI 3.14159265358979323846
#define RQ_MAX 0.1 /* largest proximity query radius, m */
/* The fast method: the deepest a cloth vertex may be inside the collider and still be pushed out
 * of the nearest surface (deeper, the nearest surface of a thin limb may be its far side). */
#define FAST_DEPTH 0.02
#define SLACK_BINS 256 /* histogram of contact slack in [-self_radius, self_radius), for an overflowing pass */

typedef struct xcontact {
    uint32_t v[4];
    uint8_t kin[4];      /* 1: collider vertex (infinite mass) */
    uint8_t type;        /* XC_VT: slot 0 vs triangle 1-3; XC_TV: triangle 0-2 vs slot 3; XC_EE: edge 0-1 vs edge 2-3 */
    uint8_t self;
    double n[3];         /* direction at detection, used only when the pair is (numerically) touching */
} xcontact;

enum { XC_VT = 0, XC_TV = 1, XC_EE = 2 };

/* Kinds of candidate pairs: (query, primitive). */
enum { PL_SELF_VT, PL_SELF_EE, PL_VT_COLLIDER, PL_TV_COLLIDER, PL_EE_COLLIDER, PL_COUNT };

typedef struct xpair {
    uint32_t query, prim;
} xpair;

typedef struct xpbd_state {
    xpbd_params p;
    uint32_t n, nc, ntri, nctri;
    geo_topo topo;          /* cloth */
    geo_topo ctopo;         /* collider (edges only) */

    double *xd, *vd;     /* committed state at t */
    double *xd_back, *vd_back; /* state before the last step (for a chord-safe retry) */
    bool chord_safe;     /* next step: one proximity pass for the whole frame */
    float *rec;          /* optional substep path recording (caller-owned), rec_cap + 1 states */
    uint32_t rec_cap, rec_states;
    bool split_moving;   /* detection routes moving-collider pairs to dmin_mov */
    double *dmin_mov;    /* chord-safe frames: distances to moving collider geometry */
    double *bound_frame; /* chord-safe frames: bound around xs_frame for every other pair */
    double *xs_frame;
    bool have_state;     /* xd/vd match g->x (cleared by set_state) */
    double *x, *v;       /* working state */
    double *xs;          /* snapshot at the last proximity pass */
    double *xo;          /* substep start */
    double *mass, *w;
    double *bound, *dmin;
    double *kin;         /* per cloth vertex: pinned displacement over the current detection window */
    uint8_t *pinned;
    double *pin_from, *pin_to;

    double *cp, *cn;     /* collider at t and t+1 */
    double *cs, *cc;     /* collider at substep start and end */
    double *csnap;       /* collider at the last proximity pass */
    double *cdisp;       /* collider vertex displacement per substep */
    double *cwin;        /* collider vertex displacement over the current detection window */
    double *kin_step;    /* per cloth vertex: pinned displacement per substep */

    double *tri_coef;    /* 6 per triangle */
    double *tri_area;
    double *hinge_rest, *hinge_len;

    geo_bvh bvh_tri, bvh_edge, bvh_ctri, bvh_cedge;
    bool cloth_bvh_built, collider_bvh_built;
    /* Boxes of every primitive at the snapshot (lo xyz, hi xyz), made once per proximity
     * pass: the candidate filters test them instead of gathering vertices per pair. */
    double *box_tri, *box_edge, *box_ctri, *box_cedge;

    /* Candidate pairs (a Verlet list): every primitive pair whose boxes were within
     * pair_radius at the snapshot xs_pairs / cs_pairs. A proximity pass with query radius rq
     * can use it instead of the trees while rq plus the largest motion since then stays
     * inside pair_radius (see pairs_fresh). */
    xpair *pairs;
    uint32_t pair_cap, pair_count[PL_COUNT];
    bool pairs_valid;
    double pair_radius;
    double *xs_pairs, *cs_pairs;

    xcontact *contacts;
    uint32_t contact_count, contact_cap;     /* self contacts: [0, contact_count) */
    uint32_t collider_contact_count;          /* collider contacts: the last ones of the array */
    uint32_t self_cap;                        /* self contacts never take the collider share */
    double rq;           /* query radius of the current detection window */
    bool tight_contacts; /* the second sweep of an overflowing pass: contacts by the final bounds */
    double slack_cutoff; /* tight sweeps keep pairs whose slack (gap left at the bounds) is below this */
    bool count_slack;    /* the second sweep histograms the slack of every pair it wants */
    uint32_t slack_hist[SLACK_BINS];
    uint64_t self_dropped; /* self contacts dropped for want of room, ever (detect() compares it) */

    /* WEFT_METHOD_XPBD_FAST: the game-engine collision projection replaces the bounds and the
     * contact lists, which are then not allocated. */
    bool fast;
    const uint8_t *held; /* weft__xpbd_set_bounded_projection: held to the bounds after the projection */
    const uint8_t *untangle_mask; /* weft__xpbd_set_untangle: the cloth crossing itself at the frame before */
    xpbd_untangle ut;             /* its crossings this frame (untangle.c); not allocated for the fast method */
    bool untangling;              /* this frame starts with marked cloth on a crossing */
    bool project; /* WEFT_METHOD_XPBD with collider_projection: the fast method's collider
                   * projection each substep instead of collider contacts and their bounds */
    uint32_t *near_seed; /* per cloth vertex: its last nearest collider triangle (a search seed) */
    /* Body parts (garment/parts.c), NULL without a partition: a contact pairs a cloth vertex
     * with collider geometry of a part in its mask only. Owned by the garment. */
    const uint32_t *part_mask, *ctri_bits, *cvert_bits;
    /* Self-collision by one traversal of the triangle tree against itself: each vertex and each
     * edge is tested from one triangle only, its owner. */
    uint32_t *vert_owner; /* per cloth vertex: the first triangle holding it */
    uint32_t *tri_edge;   /* 3 per triangle: the edge (k, k+1) when this triangle owns it, else UINT32_MAX */

    xpbd_frame_stats stats;
} xpbd_state;

xpbd_params xpbd_default_params(void)
{
    xpbd_params p = {0};
    p.youngs_modulus = 1e6;
    p.poisson_ratio = 0.49;
    p.thickness = 1e-3;
    p.areal_density = 0.2;
    p.compression_scale = 1e-2;
    p.shear_scale = 0.03;
    p.friction = 0.4;
    p.gravity = 9.81;
    p.self_radius = 1.5e-3;
    p.collider_radius = 2.5e-3;
    p.query_radius = 1e-2;
    p.bound_gamma = 0.4;
    p.detect_window = 4;
    p.self_collision = true;
    return p;
}

/* ---------------------------------------------------------------------------------------- */
/* Constraint kernels                                                                        */

bool xpbd_membrane_coefficients(const double *r0, const double *r1, const double *r2, double coef[6], double *area)
{
    /* Rest frame: u along edge 0-1, v in the triangle plane (GIPC's per-triangle frame). */
    double e1[3], e2[3], nrm[3], u[3], vv[3];
    geo_sub(e1, r1, r0);
    geo_sub(e2, r2, r0);
    geo_cross(nrm, e1, e2);
    double l1 = geo_len(e1), ln = geo_len(nrm);
    if (!(l1 > 0.0) || !(ln > 1e-14 * geo_dot(e1, e1))) {
        return false;
    }
    for (int k = 0; k < 3; ++k) {
        u[k] = e1[k] / l1;
        nrm[k] /= ln;
    }
    geo_cross(vv, nrm, u);
    /* Dm = [[|e1|, e2.u], [0, e2.v]]; F = [x1-x0, x2-x0] Dm^-1. */
    double d00 = l1, d01 = geo_dot(e2, u), d11 = geo_dot(e2, vv);
    double det = d00 * d11;
    double i00 = d11 / det, i01 = -d01 / det, i11 = d00 / det; /* i10 = 0 */
    coef[1] = i00;
    coef[2] = 0.0;
    coef[0] = -i00;
    coef[4] = i01;
    coef[5] = i11;
    coef[3] = -(i01 + i11);
    *area = 0.5 * ln;
    return true;
}

double xpbd_membrane_eval(const double *x0, const double *x1, const double *x2, const double coef[6], int which,
                          double grad[9])
{
    const double *xs[3] = {x0, x1, x2};
    double fu[3] = {0, 0, 0}, fv[3] = {0, 0, 0};
    for (int i = 0; i < 3; ++i) {
        geo_axpy(fu, coef[i], xs[i]);
        geo_axpy(fv, coef[3 + i], xs[i]);
    }
    if (which == 2) {
        for (int i = 0; i < 3; ++i) {
            for (int k = 0; k < 3; ++k) {
                grad[3 * i + k] = coef[i] * fv[k] + coef[3 + i] * fu[k];
            }
        }
        return geo_dot(fu, fv);
    }
    const double *f = which == 0 ? fu : fv;
    const double *a = which == 0 ? coef : coef + 3;
    double l = geo_len(f);
    double inv = l > 1e-12 ? 1.0 / l : 0.0;
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            grad[3 * i + k] = a[i] * f[k] * inv;
        }
    }
    return l - 1.0;
}

bool xpbd_dihedral_eval(const double *x0, const double *x1, const double *x2, const double *x3, double *theta,
                        double grad[12])
{
    double e[3], a[3], b[3], na[3], nb[3];
    memset(grad, 0, 12 * sizeof(double));
    geo_sub(e, x1, x0);
    geo_sub(a, x2, x0);
    geo_sub(b, x3, x0);
    geo_cross(na, e, a);
    geo_cross(nb, b, e);
    double le2 = geo_dot(e, e), la2 = geo_dot(na, na), lb2 = geo_dot(nb, nb);
    if (!(le2 > 0.0) || !(la2 > 1e-24 * le2 * le2) || !(lb2 > 1e-24 * le2 * le2)) {
        *theta = 0.0;
        return false;
    }
    double le = sqrt(le2);
    double c[3];
    geo_cross(c, na, nb);
    double sin_t = geo_dot(c, e) / le, cos_t = geo_dot(na, nb);
    *theta = atan2(sin_t, cos_t);
    /* Wing gradients are along the wing normals (Bridson et al. 2003); the edge vertices take
     * the negated wing gradients split by where each wing projects onto the edge. */
    double t2 = geo_dot(a, e) / le2, t3 = geo_dot(b, e) / le2;
    double g2[3], g3[3];
    for (int k = 0; k < 3; ++k) {
        g2[k] = -le * na[k] / la2;
        g3[k] = -le * nb[k] / lb2;
    }
    for (int k = 0; k < 3; ++k) {
        grad[6 + k] = g2[k];
        grad[9 + k] = g3[k];
        grad[k] = -(1.0 - t2) * g2[k] - (1.0 - t3) * g3[k];
        grad[3 + k] = -t2 * g2[k] - t3 * g3[k];
    }
    return true;
}

/* ---------------------------------------------------------------------------------------- */
/* Creation                                                                                  */

#define FREE_ARR(ptr, count) weft__free(ctx, (ptr), (size_t)(count) * sizeof *(ptr))

static void state_free(const weft_context *ctx, xpbd_state *s)
{
    if (!s) {
        return;
    }
    uint32_t n = s->n, nc = s->nc;
    FREE_ARR(s->xd, 3 * n);
    FREE_ARR(s->xd_back, 3 * n);
    FREE_ARR(s->dmin_mov, n);
    FREE_ARR(s->bound_frame, n);
    FREE_ARR(s->xs_frame, 3 * n);
    FREE_ARR(s->vd_back, 3 * n);
    FREE_ARR(s->vd, 3 * n);
    FREE_ARR(s->x, 3 * n);
    FREE_ARR(s->v, 3 * n);
    FREE_ARR(s->xs, 3 * n);
    FREE_ARR(s->xo, 3 * n);
    FREE_ARR(s->mass, n);
    FREE_ARR(s->w, n);
    FREE_ARR(s->bound, n);
    FREE_ARR(s->dmin, n);
    FREE_ARR(s->kin, n);
    FREE_ARR(s->pinned, n);
    FREE_ARR(s->pin_from, 3 * n);
    FREE_ARR(s->pin_to, 3 * n);
    FREE_ARR(s->cp, 3 * nc);
    FREE_ARR(s->cn, 3 * nc);
    FREE_ARR(s->cs, 3 * nc);
    FREE_ARR(s->cc, 3 * nc);
    FREE_ARR(s->cdisp, nc);
    FREE_ARR(s->csnap, 3 * nc);
    FREE_ARR(s->cwin, nc);
    FREE_ARR(s->kin_step, n);
    FREE_ARR(s->tri_coef, 6 * s->ntri);
    FREE_ARR(s->tri_area, s->ntri);
    FREE_ARR(s->hinge_rest, s->topo.hinge_count + 1);
    FREE_ARR(s->hinge_len, s->topo.hinge_count + 1);
    FREE_ARR(s->contacts, s->contact_cap);
    FREE_ARR(s->pairs, s->pair_cap);
    FREE_ARR(s->xs_pairs, 3 * n);
    FREE_ARR(s->cs_pairs, 3 * nc);
    FREE_ARR(s->box_tri, 6 * s->ntri);
    FREE_ARR(s->box_edge, 6 * s->topo.edge_count);
    FREE_ARR(s->box_ctri, 6 * s->nctri);
    FREE_ARR(s->box_cedge, 6 * s->ctopo.edge_count);
    FREE_ARR(s->near_seed, n);
    FREE_ARR(s->vert_owner, n);
    FREE_ARR(s->tri_edge, 3 * s->ntri);
    if (s->ut.crossing) {
        xpbd_untangle_destroy(ctx, &s->ut);
    }
    geo_bvh_destroy(ctx, &s->bvh_tri);
    geo_bvh_destroy(ctx, &s->bvh_edge);
    geo_bvh_destroy(ctx, &s->bvh_ctri);
    geo_bvh_destroy(ctx, &s->bvh_cedge);
    geo_topo_destroy(ctx, &s->topo);
    geo_topo_destroy(ctx, &s->ctopo);
    weft__free(ctx, s, sizeof *s);
}

static double wrap_angle(double a)
{
    while (a > XPI) {
        a -= 2.0 * XPI;
    }
    while (a <= -XPI) {
        a += 2.0 * XPI;
    }
    return a;
}

/* Rest geometry and masses (depend on the material parameters). */
static weft_result setup_rest(weft_garment *g, xpbd_state *s)
{
    memset(s->mass, 0, s->n * sizeof(double));
    double rest[9];
    for (uint32_t t = 0; t < s->ntri; ++t) {
        const uint32_t *tri = g->triangles + 3 * (size_t)t;
        for (int i = 0; i < 3; ++i) {
            for (int k = 0; k < 3; ++k) {
                rest[3 * i + k] = g->rest[3 * (size_t)tri[i] + k];
            }
        }
        if (!xpbd_membrane_coefficients(rest, rest + 3, rest + 6, s->tri_coef + 6 * (size_t)t, &s->tri_area[t])) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "xpbd: garment triangle %u is degenerate in the rest shape",
                              t);
        }
        for (int i = 0; i < 3; ++i) {
            s->mass[tri[i]] += s->p.areal_density * s->tri_area[t] / 3.0;
        }
    }
    for (uint32_t i = 0; i < s->n; ++i) {
        if (!(s->mass[i] > 0.0)) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "xpbd: garment vertex %u belongs to no triangle", i);
        }
    }
    for (uint32_t h = 0; h < s->topo.hinge_count; ++h) {
        const uint32_t *hg = s->topo.hinges + 4 * (size_t)h;
        double p[4][3], grad[12], th;
        for (int i = 0; i < 4; ++i) {
            for (int k = 0; k < 3; ++k) {
                p[i][k] = g->rest[3 * (size_t)hg[i] + k];
            }
        }
        xpbd_dihedral_eval(p[0], p[1], p[2], p[3], &th, grad);
        s->hinge_rest[h] = th;
        double e[3];
        geo_sub(e, p[1], p[0]);
        s->hinge_len[h] = geo_len(e);
    }
    return WEFT_OK;
}

static bool params_valid(const xpbd_params *p)
{
    return p->youngs_modulus > 0 && p->poisson_ratio > -1 && p->poisson_ratio < 0.5 && p->thickness > 0 &&
           p->areal_density > 0 && p->compression_scale > 0 && p->compression_scale <= 1 && p->shear_scale >= 0 &&
           p->friction >= 0 && isfinite(p->gravity) && p->self_radius > 0 && p->collider_radius > 0 &&
           p->query_radius > p->self_radius && p->query_radius > p->collider_radius && p->bound_gamma > 0 &&
           p->bound_gamma < 0.5 && p->detect_window >= 1 && p->detect_window <= 64;
}

/* The solver state; fast: the game-collision method, without the bounds' and contacts' arrays. */
static weft_result create_state(weft_garment *g, bool fast)
{
    const weft_context *ctx = g->ctx;
    const bool project = !fast && g->collider_projection && g->collider_vertex_count > 0;
    if ((fast || project) && g->collider_vertex_count > 0 && !g->near_tree) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "xpbd: the collider tree of the projection was not made");
    }
    xpbd_state *s = weft__alloc(ctx, sizeof *s);
    if (!s) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    s->p = xpbd_default_params();
    s->fast = fast;
    s->project = project;
    s->n = g->vertex_count;
    s->nc = g->collider_vertex_count;
    s->part_mask = g->part_mask;
    s->ctri_bits = g->ctri_bits;
    s->cvert_bits = g->cvert_bits;
    s->ntri = g->triangle_count;
    s->nctri = g->collider_triangle_count;
    weft_result r = geo_topo_create(ctx, &s->topo, g->triangles, s->ntri, s->n, fast ? "xpbd-fast garment" : "xpbd garment");
    if (r != WEFT_OK) {
        weft__free(ctx, s, sizeof *s);
        return r;
    }
    if (s->nc > 0 && !fast) {
        r = geo_topo_create(ctx, &s->ctopo, g->collider_triangles, s->nctri, s->nc, NULL);
        if (r != WEFT_OK) {
            state_free(ctx, s);
            return r;
        }
    }
    uint32_t n = s->n, nc = s->nc;
    /* Contact capacity per vertex. Overflowing pairs are dropped and counted: the bounds
     * alone still prevent crossings, but a dropped pair gets no repulsion, so its gap can shrink
     * by a factor 1 - 2 gamma per pass and ends below the validator's 10 um. Cloth
     * piled up under a gripper produced about 38 self contacts per vertex per pass at 1k
     * (docs/REFSIM.md, gripper rejections), hence 64. */
    s->self_cap = fast ? 0 : 64u * n + 64u;
    s->contact_cap = fast ? 0 : s->self_cap + 8u * n + 4u * nc + 64u;
    /* Candidate pairs: a generous budget per query primitive; a pass that would overflow it
     * queries the trees directly instead (correct, only slower). */
    s->pair_cap = fast ? 0 : 96u * (n + s->topo.edge_count) + 8u * nc + 1024u;
#define ALLOC_ARR(ptr, count) ((ptr) = weft__alloc(ctx, (size_t)(count) * sizeof *(ptr)))
    bool ok = ALLOC_ARR(s->xd, 3 * n) && ALLOC_ARR(s->vd, 3 * n) && ALLOC_ARR(s->xd_back, 3 * n) &&
              ALLOC_ARR(s->vd_back, 3 * n) && ALLOC_ARR(s->x, 3 * n) && ALLOC_ARR(s->v, 3 * n) &&
              ALLOC_ARR(s->xo, 3 * n) && ALLOC_ARR(s->mass, n) && ALLOC_ARR(s->w, n) && ALLOC_ARR(s->kin, n) &&
              ALLOC_ARR(s->kin_step, n) && ALLOC_ARR(s->pinned, n) && ALLOC_ARR(s->pin_from, 3 * n) &&
              ALLOC_ARR(s->pin_to, 3 * n) && ALLOC_ARR(s->tri_coef, 6 * s->ntri) && ALLOC_ARR(s->tri_area, s->ntri) &&
              ALLOC_ARR(s->hinge_rest, s->topo.hinge_count + 1) && ALLOC_ARR(s->hinge_len, s->topo.hinge_count + 1);
    if (ok && !fast) {
        ok = ALLOC_ARR(s->dmin_mov, n) && ALLOC_ARR(s->bound_frame, n) && ALLOC_ARR(s->xs_frame, 3 * n) &&
             ALLOC_ARR(s->xs, 3 * n) && ALLOC_ARR(s->bound, n) && ALLOC_ARR(s->dmin, n) &&
             ALLOC_ARR(s->contacts, s->contact_cap) && ALLOC_ARR(s->pairs, s->pair_cap) &&
             ALLOC_ARR(s->xs_pairs, 3 * n) && ALLOC_ARR(s->box_edge, 6 * s->topo.edge_count);
    }
    ok = ok && ALLOC_ARR(s->box_tri, 6 * s->ntri);
    if (ok && nc > 0) {
        ok = ALLOC_ARR(s->cp, 3 * nc) && ALLOC_ARR(s->cn, 3 * nc) && ALLOC_ARR(s->cs, 3 * nc) &&
             ALLOC_ARR(s->cc, 3 * nc) && ALLOC_ARR(s->cdisp, nc);
    }
    if (ok && nc > 0 && !fast) {
        ok = ALLOC_ARR(s->csnap, 3 * nc) && ALLOC_ARR(s->cwin, nc) && ALLOC_ARR(s->cs_pairs, 3 * nc) &&
             ALLOC_ARR(s->box_ctri, 6 * s->nctri) && ALLOC_ARR(s->box_cedge, 6 * s->ctopo.edge_count);
    }
    if (ok && (fast || project)) {
        ok = ALLOC_ARR(s->near_seed, n);
    }
    if (ok && fast) {
        ok = ALLOC_ARR(s->vert_owner, n) && ALLOC_ARR(s->tri_edge, 3 * s->ntri);
    }
#undef ALLOC_ARR
    /* hinge arrays have one spare slot so a hinge-free mesh still gets a valid pointer */
    if (!ok) {
        state_free(ctx, s);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    ok = geo_bvh_create(ctx, &s->bvh_tri, g->triangles, s->ntri, 3) == WEFT_OK &&
         (fast || geo_bvh_create(ctx, &s->bvh_edge, s->topo.edges, s->topo.edge_count, 2) == WEFT_OK);
    if (ok && nc > 0 && !fast) {
        ok = geo_bvh_create(ctx, &s->bvh_ctri, g->collider_triangles, s->nctri, 3) == WEFT_OK &&
             geo_bvh_create(ctx, &s->bvh_cedge, s->ctopo.edges, s->ctopo.edge_count, 2) == WEFT_OK;
    }
    if (ok && !fast) {
        ok = xpbd_untangle_create(ctx, &s->ut, n, s->ntri, s->topo.edge_count) == WEFT_OK;
    }
    if (!ok) {
        state_free(ctx, s);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    r = setup_rest(g, s);
    if (r != WEFT_OK) {
        state_free(ctx, s);
        return r;
    }
    for (uint32_t i = 0; (fast || project) && i < n; ++i) {
        s->near_seed[i] = UINT32_MAX;
    }
    if (fast) {
        for (uint32_t i = 0; i < n; ++i) {
            s->vert_owner[i] = UINT32_MAX;
        }
        for (uint32_t t = 0; t < s->ntri; ++t) {
            for (int k = 0; k < 3; ++k) {
                const uint32_t v = g->triangles[3 * (size_t)t + k];
                s->vert_owner[v] = s->vert_owner[v] == UINT32_MAX ? t : s->vert_owner[v];
                s->tri_edge[3 * (size_t)t + k] = UINT32_MAX;
            }
        }
        for (uint32_t e = 0; e < s->topo.edge_count; ++e) {
            const uint32_t t = s->topo.edge_tri[2 * (size_t)e], *ed = s->topo.edges + 2 * (size_t)e;
            const uint32_t *tri = g->triangles + 3 * (size_t)t;
            for (int k = 0; k < 3; ++k) {
                const uint32_t a = tri[k], b = tri[(k + 1) % 3];
                if ((a == ed[0] && b == ed[1]) || (a == ed[1] && b == ed[0])) {
                    s->tri_edge[3 * (size_t)t + k] = e;
                }
            }
        }
    }
    g->method_state = s;
    return WEFT_OK;
}

static weft_result xpbd_create(weft_garment *g) { return create_state(g, false); }
static weft_result xpbd_fast_create(weft_garment *g) { return create_state(g, true); }

static void xpbd_destroy(weft_garment *g)
{
    state_free(g->ctx, g->method_state);
    g->method_state = NULL;
}

/* Whether the solver's double state rounds to the garment's positions (no one moved them since). */
static bool state_is_positions(const weft_garment *g, const xpbd_state *s)
{
    for (size_t i = 0; i < 3 * (size_t)s->n; ++i) {
        if ((float)s->xd[i] != g->x[i]) {
            return false;
        }
    }
    return true;
}

/* The state a step starts from when the positions were replaced: x_t, and (x_t - x_{t-1}) / dt. */
static void state_from_positions(const weft_garment *g, double *x, double *v)
{
    for (size_t i = 0; i < 3 * (size_t)g->vertex_count; ++i) {
        x[i] = g->x[i];
        v[i] = ((double)g->x[i] - (double)g->x_prev[i]) / FRAME_DT;
    }
}

static void xpbd_reset(weft_garment *g)
{
    xpbd_state *s = g->method_state;
    s->have_state = false;
}

weft_result weft__xpbd_configure(weft_garment *g, const xpbd_params *params)
{
    if (!g || !params || (g->ops != &weft__xpbd_ops && g->ops != &weft__xpbd_fast_ops)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "xpbd configure: garment is not an XPBD garment");
    }
    if (!params_valid(params)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "xpbd configure: a parameter is out of range (moduli and radii > 0, poisson in (-1, 0.5), "
                          "query radius above both contact radii, bound gamma in (0, 0.5))");
    }
    xpbd_state *s = g->method_state;
    xpbd_params old = s->p;
    s->p = *params;
    weft_result r = setup_rest(g, s);
    if (r != WEFT_OK) {
        s->p = old;
        setup_rest(g, s);
    }
    return r;
}

weft_result weft__xpbd_export_state(const weft_garment *g, double *x, double *v)
{
    if (!g || g->ops != &weft__xpbd_ops || !x || !v) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "xpbd export: needs an XPBD garment and both arrays");
    }
    const xpbd_state *s = g->method_state;
    if (!s->have_state) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "xpbd export: the garment has not stepped since its state was set");
    }
    if (!state_is_positions(g, s)) {
        /* The constraint stage moved the cloth after the solve: the next step starts from the
         * float positions (begin_frame), and so does the exported state. */
        state_from_positions(g, x, v);
        return WEFT_OK;
    }
    memcpy(x, s->xd, 3 * (size_t)s->n * sizeof(double));
    memcpy(v, s->vd, 3 * (size_t)s->n * sizeof(double));
    return WEFT_OK;
}

weft_result weft__xpbd_import_state(weft_garment *g, const double *x, const double *v)
{
    if (!g || g->ops != &weft__xpbd_ops || !x || !v) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "xpbd import: needs an XPBD garment and both arrays");
    }
    xpbd_state *s = g->method_state;
    for (size_t i = 0; i < 3 * (size_t)s->n; ++i) {
        if (!isfinite(x[i]) || !isfinite(v[i]) || (float)x[i] != g->x[i]) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                              "xpbd import: the double state is not finite or does not round to the garment's positions");
        }
    }
    memcpy(s->xd, x, 3 * (size_t)s->n * sizeof(double));
    memcpy(s->vd, v, 3 * (size_t)s->n * sizeof(double));
    s->have_state = true;
    return WEFT_OK;
}

void weft__xpbd_forget_caches(weft_garment *g)
{
    if (g && g->ops == &weft__xpbd_ops) {
        xpbd_state *s = g->method_state;
        s->pairs_valid = false;
        s->collider_bvh_built = false;
    }
}

weft_result weft__xpbd_retry_chord_safe(weft_garment *g, const float *x_t, const float *x_prev,
                                        const float *collider_t)
{
    if (!g || g->ops != &weft__xpbd_ops || !x_t || !x_prev || (g->collider_vertex_count > 0 && !collider_t)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "xpbd retry: needs an XPBD garment, both earlier frames and the collider at t");
    }
    xpbd_state *s = g->method_state;
    weft_result r = weft_garment_set_state(g, x_t, x_prev);
    if (r != WEFT_OK) {
        return r;
    }
    memcpy(s->xd, s->xd_back, 3 * (size_t)s->n * sizeof(double));
    memcpy(s->vd, s->vd_back, 3 * (size_t)s->n * sizeof(double));
    s->have_state = true; /* still checked against x_t at the next step */
    if (g->collider_vertex_count > 0) {
        memcpy(g->collider_prev, collider_t, 3 * (size_t)g->collider_vertex_count * sizeof(float));
        g->collider_next_set = false;
    }
    s->chord_safe = true;
    return WEFT_OK;
}

weft_result weft__xpbd_record_substeps(weft_garment *g, float *buffer, uint32_t capacity_substeps)
{
    if (!g || g->ops != &weft__xpbd_ops || (buffer && capacity_substeps == 0)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "xpbd record: needs an XPBD garment and a non-empty buffer");
    }
    xpbd_state *s = g->method_state;
    s->rec = buffer;
    s->rec_cap = buffer ? capacity_substeps : 0;
    s->rec_states = 0;
    return WEFT_OK;
}

weft_result weft__xpbd_set_bounded_projection(weft_garment *g, const uint8_t *mask)
{
    if (!g || g->ops != &weft__xpbd_ops || !g->method_state) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "xpbd bounded projection: needs an XPBD garment");
    }
    ((xpbd_state *)g->method_state)->held = mask;
    return WEFT_OK;
}

weft_result weft__xpbd_set_untangle(weft_garment *g, const uint8_t *mask)
{
    if (!g || g->ops != &weft__xpbd_ops || !g->method_state) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "xpbd untangle: needs an XPBD garment");
    }
    ((xpbd_state *)g->method_state)->untangle_mask = mask;
    return WEFT_OK;
}

uint32_t weft__xpbd_recorded_states(const weft_garment *g)
{
    return g && g->ops == &weft__xpbd_ops && g->method_state ? ((const xpbd_state *)g->method_state)->rec_states : 0;
}

xpbd_frame_stats weft__xpbd_last_stats(const weft_garment *g)
{
    xpbd_frame_stats st = {0};
    if (g && (g->ops == &weft__xpbd_ops || g->ops == &weft__xpbd_fast_ops) && g->method_state) {
        st = ((const xpbd_state *)g->method_state)->stats;
    }
    return st;
}

/* ---------------------------------------------------------------------------------------- */
/* Proximity detection and bounds                                                            */

typedef struct detect_ctx {
    xpbd_state *s;
    const uint32_t *tris, *ctris;
    uint32_t query;      /* the vertex or edge being queried */
    double lo[3], hi[3]; /* the query box (BVH leaves report every primitive they hold) */
    int list;            /* the pair kind being visited or collected */
    const double *prim_box; /* boxes of that kind's primitives (s->box_*) */
    bool overflow;       /* candidate collection ran out of room */
} detect_ctx;

/* False when primitive prim's box misses the query box: skips the exact distance. */
static inline bool box_hits(const detect_ctx *dc, uint32_t prim)
{
    const double *b = dc->prim_box + 6 * (size_t)prim;
    return !(b[0] > dc->hi[0] || b[3] < dc->lo[0] || b[1] > dc->hi[1] || b[4] < dc->lo[1] || b[2] > dc->hi[2] ||
             b[5] < dc->lo[2]);
}

/* The boxes of the primitives a pair list's second member indexes. */
static const double *list_boxes(const xpbd_state *s, int list)
{
    switch (list) {
    case PL_SELF_VT:
    case PL_TV_COLLIDER:
        return s->box_tri;
    case PL_SELF_EE:
        return s->box_edge;
    case PL_VT_COLLIDER:
        return s->box_ctri;
    default:
        return s->box_cedge;
    }
}

/* Boxes of count primitives of k vertices each. */
static void prim_boxes(const double *pos, const uint32_t *idx, uint32_t count, int k, double *box)
{
    for (uint32_t p = 0; p < count; ++p, idx += k, box += 6) {
        for (int a = 0; a < 3; ++a) {
            double mn = pos[3 * (size_t)idx[0] + a], mx = mn;
            for (int i = 1; i < k; ++i) {
                double v = pos[3 * (size_t)idx[i] + a];
                mn = v < mn ? v : mn;
                mx = v > mx ? v : mx;
            }
            box[a] = mn;
            box[3 + a] = mx;
        }
    }
}

static void add_contact(xpbd_state *s, const xcontact *c)
{
    if (c->self && s->contact_count < s->self_cap) {
        s->contacts[s->contact_count++] = *c;
    } else if (!c->self && s->collider_contact_count < s->contact_cap - s->self_cap) {
        s->contacts[s->contact_cap - 1 - s->collider_contact_count++] = *c;
    } else {
        s->stats.contacts_dropped++;
        s->self_dropped += c->self;
    }
}

static void lower(xpbd_state *s, uint32_t v, double d)
{
    if (d < s->dmin[v]) {
        s->dmin[v] = d;
    }
}

/* In split mode (chord-safe frames) pairs with moving kinematic geometry (collider vertices
 * or pinned cloth vertices) feed the windowed bound dmin_mov instead of the frame-level one. */
static void lower_collider(xpbd_state *s, uint32_t v, double d, double collider_motion)
{
    if (s->split_moving && collider_motion > 0.0) {
        if (d < s->dmin_mov[v]) {
            s->dmin_mov[v] = d;
        }
    } else {
        lower(s, v, d);
    }
}

/* max/min of finite values, inlined (fmax/fmin are library calls here). */
static inline double maxd(double a, double b) { return a > b ? a : b; }
static inline double mind(double a, double b) { return a < b ? a : b; }

static double kin_max3(const xpbd_state *s, const uint32_t *t)
{
    return maxd(s->kin[t[0]], maxd(s->kin[t[1]], s->kin[t[2]]));
}

/* Whether a self pair at distance de (its kinematic motion over the window already taken off)
 * can come within the self radius before the next pass, so that it needs a contact. First
 * sweep: each side may close by up to gamma de, the most its bound can be. The second sweep of a
 * pass whose contacts overflowed (tight_contacts) uses the bounds the pass ended with: the free
 * vertices stay within them, so the pair can close by at most the larger bound on each side. */
static inline bool self_contact_wanted(xpbd_state *s, double de, double bound_a, double bound_b)
{
    if (!s->tight_contacts) {
        return de * (1.0 - 2.0 * s->p.bound_gamma) < s->p.self_radius;
    }
    const double r = s->p.self_radius, slack = de - bound_a - bound_b;
    if (!(slack < r)) {
        return false;
    }
    if (s->count_slack) {
        const double u = (slack + r) / (2.0 * r) * SLACK_BINS;
        s->slack_hist[u <= 0.0 ? 0 : u >= SLACK_BINS - 1 ? SLACK_BINS - 1 : (uint32_t)u]++;
    }
    return slack < s->slack_cutoff;
}

/* Untangling: a pair whose two sides both hold marked cloth on a crossing at the step's start sets
 * no bound and no contact (both would hold the crossing). a and b: the pair's two sides, na and nb
 * vertices each. */
static bool untangling_pair(const xpbd_state *s, const uint32_t *a, int na, const uint32_t *b, int nb)
{
    if (!s->untangling) {
        return false;
    }
    const uint8_t *c = s->ut.crossing;
    bool a_crossing = false, b_crossing = false;
    for (int k = 0; k < na; ++k) {
        a_crossing |= c[a[k]] != 0;
    }
    for (int k = 0; k < nb; ++k) {
        b_crossing |= c[b[k]] != 0;
    }
    return a_crossing && b_crossing;
}

/* Cloth vertex vs cloth triangle. */
static bool visit_self_vt(uint32_t t, void *user)
{
    detect_ctx *dc = user;
    xpbd_state *s = dc->s;
    uint32_t v = dc->query;
    const uint32_t *tri = dc->tris + 3 * (size_t)t;
    if (tri[0] == v || tri[1] == v || tri[2] == v || !box_hits(dc, t) || untangling_pair(s, &v, 1, tri, 3)) {
        return true;
    }
    const double *x = s->xs;
    double b[3];
    double d = sqrt(geo_point_triangle_sq(x + 3 * (size_t)v, x + 3 * (size_t)tri[0], x + 3 * (size_t)tri[1],
                                         x + 3 * (size_t)tri[2], b));
    if (d >= s->rq) {
        return true;
    }
    if (d < s->stats.min_self_distance) {
        s->stats.min_self_distance = d;
    }
    double km = maxd(s->kin[v], kin_max3(s, tri));
    double de = d - km;
    lower_collider(s, v, de, km);
    for (int k = 0; k < 3; ++k) {
        lower_collider(s, tri[k], de, km);
    }
    if (d > 0.0 && self_contact_wanted(s, de, s->tight_contacts ? s->bound[v] : 0.0,
                                       s->tight_contacts ? maxd(s->bound[tri[0]], maxd(s->bound[tri[1]], s->bound[tri[2]]))
                                                         : 0.0)) {
        xcontact c = {.v = {v, tri[0], tri[1], tri[2]}, .type = XC_VT, .self = 1};
        for (int k = 0; k < 3; ++k) {
            double q = b[0] * x[3 * (size_t)tri[0] + k] + b[1] * x[3 * (size_t)tri[1] + k] +
                       b[2] * x[3 * (size_t)tri[2] + k];
            c.n[k] = (x[3 * (size_t)v + k] - q) / d;
        }
        add_contact(s, &c);
    }
    return true;
}

/* Cloth edge vs cloth edge (each unordered pair once). */
static bool visit_self_ee(uint32_t e2, void *user)
{
    detect_ctx *dc = user;
    xpbd_state *s = dc->s;
    uint32_t e1 = dc->query;
    if (e2 <= e1) {
        return true;
    }
    const uint32_t *a = s->topo.edges + 2 * (size_t)e1, *b = s->topo.edges + 2 * (size_t)e2;
    if (a[0] == b[0] || a[0] == b[1] || a[1] == b[0] || a[1] == b[1] || !box_hits(dc, e2) ||
        untangling_pair(s, a, 2, b, 2)) {
        return true;
    }
    const double *x = s->xs;
    double sa, tb;
    double d = sqrt(geo_segment_segment_sq(x + 3 * (size_t)a[0], x + 3 * (size_t)a[1], x + 3 * (size_t)b[0],
                                          x + 3 * (size_t)b[1], &sa, &tb));
    if (d >= s->rq) {
        return true;
    }
    if (d < s->stats.min_self_distance) {
        s->stats.min_self_distance = d;
    }
    double km = maxd(maxd(s->kin[a[0]], s->kin[a[1]]), maxd(s->kin[b[0]], s->kin[b[1]]));
    double de = d - km;
    lower_collider(s, a[0], de, km), lower_collider(s, a[1], de, km);
    lower_collider(s, b[0], de, km), lower_collider(s, b[1], de, km);
    if (d > 0.0 && self_contact_wanted(s, de, s->tight_contacts ? maxd(s->bound[a[0]], s->bound[a[1]]) : 0.0,
                                       s->tight_contacts ? maxd(s->bound[b[0]], s->bound[b[1]]) : 0.0)) {
        xcontact c = {.v = {a[0], a[1], b[0], b[1]}, .type = XC_EE, .self = 1};
        for (int k = 0; k < 3; ++k) {
            double pa = (1.0 - sa) * x[3 * (size_t)a[0] + k] + sa * x[3 * (size_t)a[1] + k];
            double pb = (1.0 - tb) * x[3 * (size_t)b[0] + k] + tb * x[3 * (size_t)b[1] + k];
            c.n[k] = (pa - pb) / d;
        }
        add_contact(s, &c);
    }
    return true;
}

/* Cloth vertex vs collider triangle. */
static bool visit_vt_collider(uint32_t t, void *user)
{
    detect_ctx *dc = user;
    xpbd_state *s = dc->s;
    uint32_t v = dc->query;
    if (s->part_mask && !(s->part_mask[v] & s->ctri_bits[t])) {
        return true; /* a body part this vertex does not collide with */
    }
    const uint32_t *tri = dc->ctris + 3 * (size_t)t;
    const double *x = s->xs, *c = s->csnap;
    double b[3];
    double d = sqrt(geo_point_triangle_sq(x + 3 * (size_t)v, c + 3 * (size_t)tri[0], c + 3 * (size_t)tri[1],
                                         c + 3 * (size_t)tri[2], b));
    if (d >= s->rq) {
        return true;
    }
    if (d < s->stats.min_collider_distance) {
        s->stats.min_collider_distance = d;
    }
    double D = maxd(s->cwin[tri[0]], maxd(s->cwin[tri[1]], s->cwin[tri[2]]));
    double de = d - D - s->kin[v];
    lower_collider(s, v, de, D);
    /* Only pairs that can come within the contact radius inside the window need a contact. */
    if (d > 0.0 && de * (1.0 - s->p.bound_gamma) < s->p.collider_radius) {
        xcontact ct = {.v = {v, tri[0], tri[1], tri[2]}, .kin = {0, 1, 1, 1}, .type = XC_VT};
        for (int k = 0; k < 3; ++k) {
            double q = b[0] * c[3 * (size_t)tri[0] + k] + b[1] * c[3 * (size_t)tri[1] + k] +
                       b[2] * c[3 * (size_t)tri[2] + k];
            ct.n[k] = (x[3 * (size_t)v + k] - q) / d;
        }
        add_contact(s, &ct);
    }
    return true;
}

/* Collider vertex vs cloth triangle. */
static bool visit_tv_collider(uint32_t t, void *user)
{
    detect_ctx *dc = user;
    xpbd_state *s = dc->s;
    uint32_t u = dc->query;
    const uint32_t *tri = dc->tris + 3 * (size_t)t;
    if (s->part_mask &&
        !(s->cvert_bits[u] & (s->part_mask[tri[0]] | s->part_mask[tri[1]] | s->part_mask[tri[2]]))) {
        return true;
    }
    const double *x = s->xs, *c = s->csnap;
    double b[3];
    double d = sqrt(geo_point_triangle_sq(c + 3 * (size_t)u, x + 3 * (size_t)tri[0], x + 3 * (size_t)tri[1],
                                         x + 3 * (size_t)tri[2], b));
    if (d >= s->rq) {
        return true;
    }
    if (d < s->stats.min_collider_distance) {
        s->stats.min_collider_distance = d;
    }
    double de = d - s->cwin[u] - kin_max3(s, tri);
    for (int k = 0; k < 3; ++k) {
        lower_collider(s, tri[k], de, s->cwin[u]);
    }
    if (d > 0.0 && de * (1.0 - s->p.bound_gamma) < s->p.collider_radius) {
        xcontact ct = {.v = {tri[0], tri[1], tri[2], u}, .kin = {0, 0, 0, 1}, .type = XC_TV};
        for (int k = 0; k < 3; ++k) {
            double q = b[0] * x[3 * (size_t)tri[0] + k] + b[1] * x[3 * (size_t)tri[1] + k] +
                       b[2] * x[3 * (size_t)tri[2] + k];
            ct.n[k] = (q - c[3 * (size_t)u + k]) / d;
        }
        add_contact(s, &ct);
    }
    return true;
}

/* Cloth edge vs collider edge. */
static bool visit_ee_collider(uint32_t ce, void *user)
{
    detect_ctx *dc = user;
    xpbd_state *s = dc->s;
    const uint32_t *a = s->topo.edges + 2 * (size_t)dc->query, *b = s->ctopo.edges + 2 * (size_t)ce;
    if (s->part_mask && !((s->cvert_bits[b[0]] & s->cvert_bits[b[1]]) & (s->part_mask[a[0]] | s->part_mask[a[1]]))) {
        return true;
    }
    const double *x = s->xs, *c = s->csnap;
    double sa, tb;
    double d = sqrt(geo_segment_segment_sq(x + 3 * (size_t)a[0], x + 3 * (size_t)a[1], c + 3 * (size_t)b[0],
                                          c + 3 * (size_t)b[1], &sa, &tb));
    if (d >= s->rq) {
        return true;
    }
    if (d < s->stats.min_collider_distance) {
        s->stats.min_collider_distance = d;
    }
    double de = d - maxd(s->cwin[b[0]], s->cwin[b[1]]) - maxd(s->kin[a[0]], s->kin[a[1]]);
    lower_collider(s, a[0], de, maxd(s->cwin[b[0]], s->cwin[b[1]]));
    lower_collider(s, a[1], de, maxd(s->cwin[b[0]], s->cwin[b[1]]));
    if (d > 0.0 && de * (1.0 - s->p.bound_gamma) < s->p.collider_radius) {
        xcontact ct = {.v = {a[0], a[1], b[0], b[1]}, .kin = {0, 0, 1, 1}, .type = XC_EE};
        for (int k = 0; k < 3; ++k) {
            double pa = (1.0 - sa) * x[3 * (size_t)a[0] + k] + sa * x[3 * (size_t)a[1] + k];
            double pb = (1.0 - tb) * c[3 * (size_t)b[0] + k] + tb * c[3 * (size_t)b[1] + k];
            ct.n[k] = (pa - pb) / d;
        }
        add_contact(s, &ct);
    }
    return true;
}

static void box_around(const double *p, double r, double lo[3], double hi[3])
{
    for (int k = 0; k < 3; ++k) {
        lo[k] = p[k] - r;
        hi[k] = p[k] + r;
    }
}

static void box_edge(const double *p, const double *q, double r, double lo[3], double hi[3])
{
    for (int k = 0; k < 3; ++k) {
        lo[k] = mind(p[k], q[k]) - r;
        hi[k] = maxd(p[k], q[k]) + r;
    }
}

/* Candidate collection: topology filters (adjacency, each unordered self pair once) and the
 * primitive's own box against the query box (the trees report whole leaves), then the pair
 * is kept for the distance visits of later passes. */
static bool collect(detect_ctx *dc, uint32_t prim)
{
    xpbd_state *s = dc->s;
    uint32_t at = 0;
    for (int k = 0; k < PL_COUNT; ++k) {
        at += s->pair_count[k];
    }
    if (at >= s->pair_cap) {
        dc->overflow = true;
        return false; /* stop this traversal: the list is unusable for this pass */
    }
    s->pairs[at] = (xpair){dc->query, prim};
    s->pair_count[dc->list]++;
    return true;
}

static bool collect_self_vt(uint32_t t, void *user)
{
    detect_ctx *dc = user;
    const uint32_t *tri = dc->tris + 3 * (size_t)t;
    uint32_t v = dc->query;
    return tri[0] == v || tri[1] == v || tri[2] == v || !box_hits(dc, t) || collect(dc, t);
}

static bool collect_self_ee(uint32_t e2, void *user)
{
    detect_ctx *dc = user;
    const xpbd_state *s = dc->s;
    uint32_t e1 = dc->query;
    const uint32_t *a = s->topo.edges + 2 * (size_t)e1, *b = s->topo.edges + 2 * (size_t)e2;
    return e2 <= e1 || a[0] == b[0] || a[0] == b[1] || a[1] == b[0] || a[1] == b[1] || !box_hits(dc, e2) ||
           collect(dc, e2);
}

static bool collect_any(uint32_t prim, void *user) { return !box_hits(user, prim) || collect(user, prim); }

typedef struct pass_fns {
    geo_bvh_visit_fn *self_vt, *self_ee, *vt_collider, *tv_collider, *ee_collider;
} pass_fns;

/* The five tree traversals of a proximity pass with query radius r: each query primitive's
 * box grown by r against the other side's tree. fns either visit (distances, bounds,
 * contacts) or collect candidate pairs. False when a collector overflowed. */
static bool traverse(weft_garment *g, xpbd_state *s, double r, const pass_fns *fns, detect_ctx *dc)
{
    if (s->p.self_collision) {
        dc->list = PL_SELF_VT;
        dc->prim_box = list_boxes(s, PL_SELF_VT);
        for (uint32_t v = 0; v < s->n && !dc->overflow; ++v) {
            dc->query = v;
            box_around(s->xs + 3 * (size_t)v, r, dc->lo, dc->hi);
            geo_bvh_query(&s->bvh_tri, dc->lo, dc->hi, fns->self_vt, dc);
        }
        dc->list = PL_SELF_EE;
        dc->prim_box = list_boxes(s, PL_SELF_EE);
        for (uint32_t e = 0; e < s->topo.edge_count && !dc->overflow; ++e) {
            const uint32_t *ed = s->topo.edges + 2 * (size_t)e;
            dc->query = e;
            box_edge(s->xs + 3 * (size_t)ed[0], s->xs + 3 * (size_t)ed[1], r, dc->lo, dc->hi);
            geo_bvh_query_above(&s->bvh_edge, dc->lo, dc->hi, e, fns->self_ee, dc);
        }
    }
    if (s->nc > 0 && !s->project) {
        (void)g;
        const geo_bvh_node *root = &s->bvh_tri.nodes[0];
        dc->list = PL_VT_COLLIDER;
        dc->prim_box = list_boxes(s, PL_VT_COLLIDER);
        for (uint32_t v = 0; v < s->n && !dc->overflow; ++v) {
            dc->query = v;
            box_around(s->xs + 3 * (size_t)v, r, dc->lo, dc->hi);
            geo_bvh_query(&s->bvh_ctri, dc->lo, dc->hi, fns->vt_collider, dc);
        }
        dc->list = PL_TV_COLLIDER;
        dc->prim_box = list_boxes(s, PL_TV_COLLIDER);
        for (uint32_t u = 0; u < s->nc && !dc->overflow; ++u) {
            const double *p = s->csnap + 3 * (size_t)u;
            /* Cheap reject against the whole cloth box. */
            if (p[0] < root->lo[0] - r || p[0] > root->hi[0] + r || p[1] < root->lo[1] - r || p[1] > root->hi[1] + r ||
                p[2] < root->lo[2] - r || p[2] > root->hi[2] + r) {
                continue;
            }
            dc->query = u;
            box_around(p, r, dc->lo, dc->hi);
            geo_bvh_query(&s->bvh_tri, dc->lo, dc->hi, fns->tv_collider, dc);
        }
        dc->list = PL_EE_COLLIDER;
        dc->prim_box = list_boxes(s, PL_EE_COLLIDER);
        for (uint32_t e = 0; e < s->topo.edge_count && !dc->overflow; ++e) {
            const uint32_t *ed = s->topo.edges + 2 * (size_t)e;
            dc->query = e;
            box_edge(s->xs + 3 * (size_t)ed[0], s->xs + 3 * (size_t)ed[1], r, dc->lo, dc->hi);
            geo_bvh_query(&s->bvh_cedge, dc->lo, dc->hi, fns->ee_collider, dc);
        }
    }
    return !dc->overflow;
}

/* Largest displacement of n points between two xyz arrays. */
static double max_motion(const double *a, const double *b, uint32_t n)
{
    double m2 = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        double d[3];
        geo_sub(d, a + 3 * (size_t)i, b + 3 * (size_t)i);
        double l2 = geo_dot(d, d);
        m2 = l2 > m2 ? l2 : m2;
    }
    return sqrt(m2);
}

/* The candidate pairs still cover this pass: two primitives whose boxes (grown by rq) overlap
 * now had boxes within rq + their motion since the lists were built, at most 2 dx for a
 * cloth pair and dx + dc for a cloth-collider pair (per axis, each vertex moved at most its
 * Euclidean displacement). */
static bool pairs_fresh(const xpbd_state *s)
{
    if (!s->pairs_valid) {
        return false;
    }
    double dx = max_motion(s->xs, s->xs_pairs, s->n);
    double dcol = s->nc > 0 ? max_motion(s->csnap, s->cs_pairs, s->nc) : 0.0;
    return s->rq + 2.0 * dx + dcol <= s->pair_radius;
}

static void refit_trees(xpbd_state *s)
{
    if (!s->cloth_bvh_built) {
        geo_bvh_build(&s->bvh_tri, s->xs);
        geo_bvh_build(&s->bvh_edge, s->xs);
        s->cloth_bvh_built = true;
    }
    if (!s->collider_bvh_built && s->nc > 0) {
        geo_bvh_build(&s->bvh_ctri, s->csnap);
        geo_bvh_build(&s->bvh_cedge, s->csnap);
        s->collider_bvh_built = true;
    }
    geo_bvh_refit(&s->bvh_tri, s->xs, NULL, 0.0);
    geo_bvh_refit(&s->bvh_edge, s->xs, NULL, 0.0);
    if (s->nc > 0) {
        geo_bvh_refit(&s->bvh_ctri, s->csnap, NULL, 0.0);
        geo_bvh_refit(&s->bvh_cedge, s->csnap, NULL, 0.0);
    }
}

/* Rebuilds the candidate lists at the current snapshot with radius rq plus a skin of
 * half the minimum query radius (room for motion before the next rebuild; 1x and 0.25x were
 * 7 % and 15 % slower on a skirt drape). */
static bool build_pairs(weft_garment *g, xpbd_state *s)
{
    refit_trees(s);
    memset(s->pair_count, 0, sizeof s->pair_count);
    s->pair_radius = s->rq + 0.5 * s->p.query_radius;
    detect_ctx dc = {.s = s, .tris = g->triangles, .ctris = g->collider_triangles};
    const pass_fns collectors = {collect_self_vt, collect_self_ee, collect_any, collect_any, collect_any};
    s->pairs_valid = traverse(g, s, s->pair_radius, &collectors, &dc);
    if (s->pairs_valid) {
        memcpy(s->xs_pairs, s->xs, 3 * (size_t)s->n * sizeof(double));
        if (s->nc > 0) {
            memcpy(s->cs_pairs, s->csnap, 3 * (size_t)s->nc * sizeof(double));
        }
        s->stats.pair_rebuilds++;
    }
    return s->pairs_valid;
}

/* Query box of a cached pair's query primitive, as traverse() would build it. */
static void query_box(const xpbd_state *s, int list, uint32_t q, detect_ctx *dc)
{
    if (list == PL_SELF_VT || list == PL_VT_COLLIDER) {
        box_around(s->xs + 3 * (size_t)q, s->rq, dc->lo, dc->hi);
    } else if (list == PL_TV_COLLIDER) {
        box_around(s->csnap + 3 * (size_t)q, s->rq, dc->lo, dc->hi);
    } else {
        const uint32_t *ed = s->topo.edges + 2 * (size_t)q;
        box_edge(s->xs + 3 * (size_t)ed[0], s->xs + 3 * (size_t)ed[1], s->rq, dc->lo, dc->hi);
    }
}

/* Visits every pair within rq once: over the candidate lists when use_lists, else straight
 * from the trees. */
static void sweep(weft_garment *g, xpbd_state *s, detect_ctx *dc, bool use_lists)
{
    static geo_bvh_visit_fn *const visitors[PL_COUNT] = {visit_self_vt, visit_self_ee, visit_vt_collider,
                                                      visit_tv_collider, visit_ee_collider};
    if (use_lists) {
        const xpair *pr = s->pairs;
        for (int list = 0; list < PL_COUNT; ++list) {
            uint32_t last = UINT32_MAX;
            dc->list = list;
            dc->prim_box = list_boxes(s, list);
            for (uint32_t k = 0; k < s->pair_count[list]; ++k, ++pr) {
                if (pr->query != last) {
                    last = pr->query;
                    dc->query = last;
                    query_box(s, list, last, dc);
                }
                /* The trees only report primitives whose boxes meet the query box. */
                if (box_hits(dc, pr->prim)) {
                    visitors[list](pr->prim, dc);
                }
            }
        }
    } else {
        const pass_fns direct = {visit_self_vt, visit_self_ee, visit_vt_collider, visit_tv_collider, visit_ee_collider};
        traverse(g, s, s->rq, &direct, dc);
    }
}

/* One proximity pass at the snapshot s->xs / s->csnap; window = substeps until the next pass.
 * Distances are visited over the candidate lists when they are fresh (rebuilt when not),
 * else straight from the trees. Both give every pair within rq.
 *
 * A pass whose self contacts overflow the list sweeps a second time for the contacts alone,
 * keeping only the pairs that its final bounds let close to the self radius. A dropped pair
 * keeps its bound and cannot cross, but gets no repulsion either, so in a dense pile (a
 * finely meshed sheet folded under a gripper) its gap shrinks pass after pass until the
 * validator sees it touch. Passes that fit are swept once, as before. */
static void detect(weft_garment *g, xpbd_state *s)
{
    const double gamma = s->p.bound_gamma;
    s->contact_count = 0;
    s->collider_contact_count = 0;
    s->stats.detections++;
    for (uint32_t i = 0; i < s->n; ++i) {
        s->dmin[i] = s->rq;
        s->dmin_mov[i] = s->rq;
    }
    prim_boxes(s->xs, g->triangles, s->ntri, 3, s->box_tri);
    prim_boxes(s->xs, s->topo.edges, s->topo.edge_count, 2, s->box_edge);
    if (s->nc > 0) {
        prim_boxes(s->csnap, g->collider_triangles, s->nctri, 3, s->box_ctri);
        prim_boxes(s->csnap, s->ctopo.edges, s->ctopo.edge_count, 2, s->box_cedge);
    }
    detect_ctx dc = {.s = s, .tris = g->triangles, .ctris = g->collider_triangles};
    const bool use_lists = pairs_fresh(s) || build_pairs(g, s);
    if (!use_lists) {
        refit_trees(s);
    }
    const uint32_t dropped_before = s->stats.contacts_dropped;
    const uint32_t self_dropped_before = s->self_dropped;
    sweep(g, s, &dc, use_lists);
    for (uint32_t i = 0; i < s->n; ++i) {
        double d = s->dmin[i];
        s->bound[i] = d > 0.0 ? gamma * d : 0.0;
    }
    if (s->self_dropped > self_dropped_before && !s->split_moving) {
        /* Revisiting lowers no distance further, so the bounds stay as they are. */
        const double r = s->p.self_radius;
        s->tight_contacts = true;
        s->slack_cutoff = r;
        s->count_slack = true;
        memset(s->slack_hist, 0, sizeof s->slack_hist);
        for (int round = 0; round < 2; ++round) {
            s->contact_count = 0;
            s->collider_contact_count = 0;
            s->stats.contacts_dropped = dropped_before;
            const uint64_t before = s->self_dropped;
            sweep(g, s, &dc, use_lists);
            s->count_slack = false;
            if (s->self_dropped == before) {
                break;
            }
            /* Still too many: a third sweep keeps the pairs with the least slack, as many as fit
             * (the cutoff is a bin edge of the second sweep's histogram). The pairs left out have
             * the most room; as gaps close, they are the ones kept. */
            uint64_t kept = 0;
            uint32_t bins = 0;
            while (bins < SLACK_BINS && kept + s->slack_hist[bins] <= s->self_cap) {
                kept += s->slack_hist[bins++];
            }
            s->slack_cutoff = -r + 2.0 * r * (double)(bins > 0 ? bins : 1) / SLACK_BINS;
        }
        s->tight_contacts = false;
        s->stats.tight_passes++;
    }
}

/* ---------------------------------------------------------------------------------------- */
/* Projection                                                                                */

static inline double *pos_of(xpbd_state *s, uint32_t idx, uint8_t kin) { return (kin ? s->cc : s->x) + 3 * (size_t)idx; }

/* Closest features of a contact pair at the current positions: coefficients c such that
 * sum_i c_i y_i is the separation vector, and its unit direction n. The unsigned distance is
 * safe because the bounds never let a pair pass through zero separation. */
static double contact_refresh(xpbd_state *s, const xcontact *ct, double c[4], double n[3])
{
    const double *y[4];
    for (int i = 0; i < 4; ++i) {
        y[i] = pos_of(s, ct->v[i], ct->kin[i]);
    }
    double b[3], sa, tb;
    if (ct->type == XC_VT) {
        geo_point_triangle_sq(y[0], y[1], y[2], y[3], b);
        c[0] = 1.0, c[1] = -b[0], c[2] = -b[1], c[3] = -b[2];
    } else if (ct->type == XC_TV) {
        geo_point_triangle_sq(y[3], y[0], y[1], y[2], b);
        c[0] = b[0], c[1] = b[1], c[2] = b[2], c[3] = -1.0;
    } else {
        geo_segment_segment_sq(y[0], y[1], y[2], y[3], &sa, &tb);
        c[0] = 1.0 - sa, c[1] = sa, c[2] = -(1.0 - tb), c[3] = -tb;
    }
    double d[3] = {0, 0, 0};
    for (int i = 0; i < 4; ++i) {
        geo_axpy(d, c[i], y[i]);
    }
    double len = geo_len(d);
    if (len > 1e-12) {
        for (int k = 0; k < 3; ++k) {
            n[k] = d[k] / len;
        }
    } else {
        for (int k = 0; k < 3; ++k) {
            n[k] = ct->n[k];
        }
    }
    return geo_dot(d, n);
}

static uint32_t solve_contacts(xpbd_state *s)
{
    uint32_t active = 0;
    const double mu = s->p.friction;
    for (uint32_t j = 0; j < s->contact_count + s->collider_contact_count; ++j) {
        uint32_t k = j < s->contact_count ? j : s->contact_cap - 1 - (j - s->contact_count);
        const xcontact *ct = &s->contacts[k];
        double r = ct->self ? s->p.self_radius : s->p.collider_radius;
        double cc[4], n[3];
        double C = contact_refresh(s, ct, cc, n) - r;
        if (C >= 0.0) {
            continue;
        }
        double W = 0.0, wi[4];
        for (int i = 0; i < 4; ++i) {
            wi[i] = ct->kin[i] ? 0.0 : s->w[ct->v[i]];
            W += wi[i] * cc[i] * cc[i];
        }
        if (!(W > 0.0)) {
            continue;
        }
        active++;
        double dl = -C / W;
        for (int i = 0; i < 4; ++i) {
            if (wi[i] > 0.0) {
                geo_axpy(pos_of(s, ct->v[i], 0), wi[i] * cc[i] * dl, n);
            }
        }
        if (mu <= 0.0) {
            continue;
        }
        /* Coulomb friction on the relative tangential displacement over this substep. */
        double u[3] = {0, 0, 0};
        for (int i = 0; i < 4; ++i) {
            const double *y = pos_of(s, ct->v[i], ct->kin[i]);
            const double *y0 = (ct->kin[i] ? s->cs : s->xo) + 3 * (size_t)ct->v[i];
            for (int a = 0; a < 3; ++a) {
                u[a] += cc[i] * (y[a] - y0[a]);
            }
        }
        double un = geo_dot(u, n);
        geo_axpy(u, -un, n);
        double ut = geo_len(u);
        if (!(ut > 0.0)) {
            continue;
        }
        double limit = mu * (-C);
        double scale = ut <= limit ? 1.0 : limit / ut;
        for (int i = 0; i < 4; ++i) {
            if (wi[i] > 0.0) {
                geo_axpy(pos_of(s, ct->v[i], 0), -wi[i] * cc[i] * scale / W, u);
            }
        }
    }
    return active;
}

static void solve_elastic(weft_garment *g, xpbd_state *s, double h)
{
    const double mu_h = s->p.youngs_modulus * s->p.thickness / (2.0 * (1.0 + s->p.poisson_ratio));
    const double inv_h2 = 1.0 / (h * h);
    double grad[12];
    for (uint32_t t = 0; t < s->ntri; ++t) {
        const uint32_t *tri = g->triangles + 3 * (size_t)t;
        double *x0 = s->x + 3 * (size_t)tri[0], *x1 = s->x + 3 * (size_t)tri[1], *x2 = s->x + 3 * (size_t)tri[2];
        double w0 = s->w[tri[0]], w1 = s->w[tri[1]], w2 = s->w[tri[2]];
        if (w0 + w1 + w2 == 0.0) {
            continue;
        }
        const double *coef = s->tri_coef + 6 * (size_t)t;
        double area = s->tri_area[t];
        for (int which = 0; which < 3; ++which) {
            double C = xpbd_membrane_eval(x0, x1, x2, coef, which, grad);
            double k;
            if (which == 2) {
                k = 2.0 * area * s->p.shear_scale * mu_h;
            } else {
                k = 2.0 * area * mu_h * (C < 0.0 ? s->p.compression_scale : 1.0);
            }
            if (!(k > 0.0)) {
                continue;
            }
            double alpha = inv_h2 / k;
            double W = w0 * geo_dot(grad, grad) + w1 * geo_dot(grad + 3, grad + 3) + w2 * geo_dot(grad + 6, grad + 6);
            double dl = -C / (W + alpha);
            geo_axpy(x0, w0 * dl, grad);
            geo_axpy(x1, w1 * dl, grad + 3);
            geo_axpy(x2, w2 * dl, grad + 6);
        }
    }
    const double nu = s->p.poisson_ratio;
    const double kb = s->p.youngs_modulus * s->p.thickness * s->p.thickness * s->p.thickness / (24.0 * (1.0 - nu * nu));
    for (uint32_t hi = 0; hi < s->topo.hinge_count; ++hi) {
        const uint32_t *hg = s->topo.hinges + 4 * (size_t)hi;
        double *p[4];
        double wsum = 0.0, wv[4];
        for (int i = 0; i < 4; ++i) {
            p[i] = s->x + 3 * (size_t)hg[i];
            wv[i] = s->w[hg[i]];
            wsum += wv[i];
        }
        if (wsum == 0.0) {
            continue;
        }
        double th;
        if (!xpbd_dihedral_eval(p[0], p[1], p[2], p[3], &th, grad)) {
            continue;
        }
        double C = wrap_angle(th - s->hinge_rest[hi]);
        double alpha = inv_h2 / (2.0 * kb * s->hinge_len[hi]);
        double W = 0.0;
        for (int i = 0; i < 4; ++i) {
            W += wv[i] * geo_dot(grad + 3 * i, grad + 3 * i);
        }
        double dl = -C / (W + alpha);
        for (int i = 0; i < 4; ++i) {
            geo_axpy(p[i], wv[i] * dl, grad + 3 * i);
        }
    }
}

/* Strain and elastic energy of the committed state (for statistics). */
static void measure(weft_garment *g, xpbd_state *s)
{
    const double mu_h = s->p.youngs_modulus * s->p.thickness / (2.0 * (1.0 + s->p.poisson_ratio));
    const double nu = s->p.poisson_ratio;
    const double kb = s->p.youngs_modulus * s->p.thickness * s->p.thickness * s->p.thickness / (24.0 * (1.0 - nu * nu));
    double grad[12], max_strain = 0.0, energy = 0.0;
    for (uint32_t t = 0; t < s->ntri; ++t) {
        const uint32_t *tri = g->triangles + 3 * (size_t)t;
        const double *coef = s->tri_coef + 6 * (size_t)t;
        const double *x0 = s->xd + 3 * (size_t)tri[0], *x1 = s->xd + 3 * (size_t)tri[1], *x2 = s->xd + 3 * (size_t)tri[2];
        for (int which = 0; which < 3; ++which) {
            double C = xpbd_membrane_eval(x0, x1, x2, coef, which, grad);
            double k = which == 2 ? 2.0 * s->tri_area[t] * s->p.shear_scale * mu_h
                                  : 2.0 * s->tri_area[t] * mu_h * (C < 0.0 ? s->p.compression_scale : 1.0);
            energy += 0.5 * k * C * C;
            if (which < 2 && C > max_strain) {
                max_strain = C;
            }
        }
    }
    for (uint32_t hi = 0; hi < s->topo.hinge_count; ++hi) {
        const uint32_t *hg = s->topo.hinges + 4 * (size_t)hi;
        double th;
        if (xpbd_dihedral_eval(s->xd + 3 * (size_t)hg[0], s->xd + 3 * (size_t)hg[1], s->xd + 3 * (size_t)hg[2],
                               s->xd + 3 * (size_t)hg[3], &th, grad)) {
            double C = wrap_angle(th - s->hinge_rest[hi]);
            energy += kb * s->hinge_len[hi] * C * C;
        }
    }
    s->stats.max_strain = max_strain;
    s->stats.elastic_energy = energy;
}

/* The most a collider vertex may move per window when substeps adapt to it: cloth held at the
 * contact radius r and pushed by geometry moving D per window retreats at most gamma (gap - D)
 * per window, so the gap shrinks window after window unless D < gamma / (1 + gamma) r (the
 * window rule in xpbd_step); 0.8 of that leaves a margin, as for pinned vertices. */
static double fast_collider_step(const xpbd_params *p)
{
    return 0.8 * p->bound_gamma / (1.0 + p->bound_gamma) * p->collider_radius;
}

/* How far the collider geometry that can reach the cloth this frame moves in it: the largest
 * frame displacement of the vertices of collider triangles whose swept box (start and end of
 * the frame) meets the cloth's box grown by a margin (5 cm, or twice the cloth's fastest travel
 * over the last frame). A foot far below a T-shirt does not count. The validator still
 * certifies every frame, so this only decides the substeps, never what is accepted. */
static double near_collider_travel(const weft_garment *g, const xpbd_state *s)
{
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double fastest2 = 0.0;
    for (uint32_t i = 0; i < s->n; ++i) {
        const float *x = g->x + 3 * (size_t)i, *xp = g->x_prev + 3 * (size_t)i;
        double d2 = 0.0;
        for (int a = 0; a < 3; ++a) {
            lo[a] = fminf(lo[a], x[a]);
            hi[a] = fmaxf(hi[a], x[a]);
            d2 += ((double)x[a] - xp[a]) * ((double)x[a] - xp[a]);
        }
        fastest2 = d2 > fastest2 ? d2 : fastest2;
    }
    const float margin = (float)fmax(0.05, 2.0 * sqrt(fastest2));
    double travel2 = 0.0;
    for (uint32_t t = 0; t < s->nctri; ++t) {
        const uint32_t *tri = g->collider_triangles + 3 * (size_t)t;
        bool meets = true;
        for (int a = 0; a < 3 && meets; ++a) {
            float tlo = INFINITY, thi = -INFINITY;
            for (int k = 0; k < 3; ++k) {
                const float p = g->collider_prev[3 * (size_t)tri[k] + a], q = g->collider_next[3 * (size_t)tri[k] + a];
                tlo = fminf(tlo, fminf(p, q));
                thi = fmaxf(thi, fmaxf(p, q));
            }
            meets = thi >= lo[a] - margin && tlo <= hi[a] + margin;
        }
        for (int k = 0; k < 3 && meets; ++k) {
            double d2 = 0.0;
            for (int a = 0; a < 3; ++a) {
                const double d = (double)g->collider_next[3 * (size_t)tri[k] + a] - g->collider_prev[3 * (size_t)tri[k] + a];
                d2 += d * d;
            }
            travel2 = d2 > travel2 ? d2 : travel2;
        }
    }
    return sqrt(travel2);
}

/* The frame's substep count. A window is at least one substep, so a collider faster than
 * fast_collider_step per substep (a hand swinging at 15 m/s, a foot at 7) runs over the cloth
 * it presses. With substeps_max above substeps, such a frame gets just enough substeps. */
static uint32_t frame_substeps(const weft_garment *g, const xpbd_params *p, double near_travel)
{
    const double need = ceil(near_travel / fast_collider_step(p));
    return need <= g->substeps ? g->substeps : need >= g->substeps_max ? g->substeps_max : (uint32_t)need;
}

/* The start of a frame of S substeps, shared by both methods: the double state at t (kept from
 * the last step unless the positions were replaced), the pins' paths, the collider at t and t+1,
 * and fresh statistics. */
static void begin_frame(weft_garment *g, xpbd_state *s, uint32_t S)
{
    const uint32_t n = s->n, nc = s->nc;
    /* The double state continues the previous frame unless the positions were replaced
     * (set_state, or a post-process that moved vertices). */
    s->have_state = s->have_state && state_is_positions(g, s);
    if (!s->have_state) {
        state_from_positions(g, s->xd, s->vd);
    }
    memcpy(s->xd_back, s->xd, 3 * (size_t)n * sizeof(double));
    memcpy(s->vd_back, s->vd, 3 * (size_t)n * sizeof(double));
    memcpy(s->x, s->xd, 3 * (size_t)n * sizeof(double));
    memcpy(s->v, s->vd, 3 * (size_t)n * sizeof(double));
    for (uint32_t i = 0; i < n; ++i) {
        s->pinned[i] = 0;
        s->w[i] = 1.0 / s->mass[i];
        s->kin[i] = 0.0;
        s->kin_step[i] = 0.0;
    }
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        uint32_t i = g->pin_indices[k];
        s->pinned[i] = 1;
        s->w[i] = 0.0;
        double d2 = 0.0;
        for (int a = 0; a < 3; ++a) {
            s->pin_from[3 * (size_t)i + a] = s->xd[3 * (size_t)i + a];
            s->pin_to[3 * (size_t)i + a] = g->pin_targets[3 * (size_t)k + a];
            double d = s->pin_to[3 * (size_t)i + a] - s->pin_from[3 * (size_t)i + a];
            d2 += d * d;
        }
        s->kin_step[i] = sqrt(d2) / S;
    }
    for (size_t i = 0; i < 3 * (size_t)nc; ++i) {
        s->cp[i] = g->collider_prev[i];
        s->cn[i] = g->collider_next[i];
    }
    for (uint32_t u = 0; u < nc; ++u) {
        double d2 = 0.0;
        for (int a = 0; a < 3; ++a) {
            double d = s->cn[3 * (size_t)u + a] - s->cp[3 * (size_t)u + a];
            d2 += d * d;
        }
        s->cdisp[u] = sqrt(d2) / S;
    }
    s->stats = (xpbd_frame_stats){.substeps = S, .min_self_distance = INFINITY, .min_collider_distance = INFINITY};
}

/* The substep's inertial prediction: gravity on the free vertices, pinned ones on their paths at
 * the substep's end (fraction a1 of the frame). */
static void predict(xpbd_state *s, double h, double a1)
{
    for (uint32_t i = 0; i < s->n; ++i) {
        double *xi = s->x + 3 * (size_t)i, *vi = s->v + 3 * (size_t)i;
        if (s->pinned[i]) {
            for (int a = 0; a < 3; ++a) {
                xi[a] = s->pin_from[3 * (size_t)i + a] + a1 * (s->pin_to[3 * (size_t)i + a] - s->pin_from[3 * (size_t)i + a]);
            }
            continue;
        }
        vi[1] -= s->p.gravity * h;
        geo_axpy(xi, h, vi);
    }
}

/* The end of a frame: the state is committed (and written to x_next) only when finite. */
static weft_result end_frame(weft_garment *g, xpbd_state *s)
{
    const uint32_t n = s->n;
    for (size_t i = 0; i < 3 * (size_t)n; ++i) {
        if (!isfinite(s->x[i]) || !isfinite(s->v[i])) {
            return weft__fail(WEFT_ERROR_NOT_FINITE, "xpbd: the solve produced NaN or infinity at vertex %zu; state kept",
                              i / 3);
        }
    }
    memcpy(s->xd, s->x, 3 * (size_t)n * sizeof(double));
    memcpy(s->vd, s->v, 3 * (size_t)n * sizeof(double));
    s->have_state = true;
    for (size_t i = 0; i < 3 * (size_t)n; ++i) {
        g->x_next[i] = (float)s->xd[i];
    }
    /* Nothing nearer than the radius searched: report that radius. */
    if (!isfinite(s->stats.min_self_distance)) {
        s->stats.min_self_distance = s->fast ? s->p.self_radius : s->rq;
    }
    if (!isfinite(s->stats.min_collider_distance)) {
        s->stats.min_collider_distance = s->fast || s->project ? s->p.collider_radius + FAST_DEPTH : s->rq;
    }
    measure(g, s);
    return WEFT_OK;
}

static uint32_t fast_collide_body(weft_garment *g, xpbd_state *s);

/* x moved back onto the ball of radius r around c when it left it; whether it moved. */
static bool hold_to_bound(double *x, const double *c, double r)
{
    double d[3];
    geo_sub(d, x, c);
    const double l = geo_len(d);
    if (l <= r) {
        return false;
    }
    const double f = l > 0.0 ? r / l : 0.0;
    for (int a = 0; a < 3; ++a) {
        x[a] = c[a] + f * d[a];
    }
    return true;
}

/* Vertex i back within its conservative bounds: around its position at the frame's start when
 * the frame is split (chord-safe frames), then around the window's start. Returns the clamps
 * that moved it (0..2). */
static uint32_t hold_to_bounds(xpbd_state *s, uint32_t i, bool split)
{
    double *xi = s->x + 3 * (size_t)i;
    uint32_t moved = split && hold_to_bound(xi, s->xs_frame + 3 * (size_t)i, s->bound_frame[i]);
    moved += hold_to_bound(xi, s->xs + 3 * (size_t)i, s->bound[i]);
    return moved;
}

/* Free vertices farther than their radius from their target (the skinned garment) go onto the
 * sphere. */
static void hold_max_distance(const weft_garment *g, xpbd_state *s, const float *targets)
{
    if (!targets) {
        return;
    }
    for (uint32_t i = 0; i < s->n; ++i) {
        if (s->pinned[i]) {
            continue;
        }
        double *x = s->x + 3 * (size_t)i, d[3];
        const float *t = targets + 3 * (size_t)i;
        for (int a = 0; a < 3; ++a) {
            d[a] = x[a] - (double)t[a];
        }
        const double l = geo_len(d), r = g->tether_radius[i];
        if (l > r) {
            for (int a = 0; a < 3; ++a) {
                x[a] = (double)t[a] + d[a] * (r / l);
            }
        }
    }
}

static weft_result xpbd_step(weft_garment *g)
{
    xpbd_state *s = g->method_state;
    const bool adaptive = g->substeps_max > g->substeps && s->nc > 0;
    const double near_travel = adaptive || (s->project && s->nc > 0) ? near_collider_travel(g, s) : 0.0;
    /* A projected collider moves the cloth it meets as fast as it goes: the bounds leave room
     * for that speed (cloth the bounds hold back is left inside, and goes out over the next
     * substeps; raised substeps keep the body's step within the bounds of cloth near it). */
    const double body_speed = s->project ? near_travel / FRAME_DT : 0.0;
    const uint32_t n = s->n, nc = s->nc, S = adaptive ? frame_substeps(g, &s->p, near_travel) : g->substeps;
    const bool raised = S > g->substeps;
    const double h = FRAME_DT / S;
    begin_frame(g, s, S);
    s->untangling = s->untangle_mask && !s->fast &&
                    xpbd_untangle_begin(&s->ut, &s->topo, g->triangles, s->untangle_mask, s->x) > 0;
    /* With a projected collider the max distance (tethers) is held inside the substeps, toward
     * the garment skinned onto the collider at t+1; the constraint stage's clamp after the step
     * takes the same targets (skinned_next) and moves only what the bounds held back. */
    const float *tethers = NULL;
    if (s->project && g->tether_radius && g->skin) {
        weft_result tr = geo_skin_eval(g->skin, g->collider_triangles, g->collider_next, "xpbd: max distance",
                                       g->tether_target);
        if (tr != WEFT_OK) {
            return tr;
        }
        tethers = g->tether_target;
    }
    const bool chord_safe = s->chord_safe;
    s->chord_safe = false;
    const bool record = s->rec && S <= s->rec_cap;
    s->rec_states = 0;
    if (record) {
        for (size_t i = 0; i < 3 * (size_t)n; ++i) {
            s->rec[i] = (float)s->xd[i];
        }
    }
    double cdisp_max = 0.0;
    for (uint32_t u = 0; u < nc; ++u) {
        cdisp_max = s->cdisp[u] > cdisp_max ? s->cdisp[u] : cdisp_max;
    }
    /* The cloth tree is rebuilt once per frame (the cloth may deform a lot), then refit. */
    s->cloth_bvh_built = false;
    uint32_t window = 0, since = 0, clamped_last = 0;
    /* Re-detect early only when more than 2 % of the vertices hit their bounds: a few
     * clamped vertices wait for the next regular pass (at most detect_window substeps). */
    const uint32_t clamp_redetect = n / 50;
    /* Chord-safe frames: every pair gets one bound around the frame-start position, except
     * pairs with moving kinematic geometry (collider, pins), which keep windowed passes (a
     * frame-long bound would hold the cloth still while the collider moves into it). */
    double pin_step_max = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        pin_step_max = s->kin_step[i] > pin_step_max ? s->kin_step[i] : pin_step_max;
    }
    const bool moving_pins = pin_step_max > 0.0;
    const bool split = chord_safe && (cdisp_max > 0.0 || moving_pins), frame_only = chord_safe && !split;
    s->split_moving = split;
    for (uint32_t step = 0; step < S; ++step) {
        double a0 = (double)step / S, a1 = (double)(step + 1) / S;
        for (size_t i = 0; i < 3 * (size_t)nc; ++i) {
            s->cs[i] = s->cp[i] + a0 * (s->cn[i] - s->cp[i]);
            s->cc[i] = s->cp[i] + a1 * (s->cn[i] - s->cp[i]);
        }
        memcpy(s->xo, s->x, 3 * (size_t)n * sizeof(double));
        /* A new proximity pass when the window is used up, or early when many vertices hit
         * their bounds (they cannot move further on the old bounds: avoids sticking). */
        if (split && step == 0) {
            double vmax = 0.0;
            for (uint32_t i = 0; i < n; ++i) {
                double sp = geo_len(s->v + 3 * (size_t)i);
                vmax = sp > vmax ? sp : vmax;
            }
            vmax = fmax(vmax, body_speed);
            double travel = (vmax + s->p.gravity * h * S) * h * S;
            s->rq = fmin(fmax(s->p.query_radius, travel / s->p.bound_gamma + 2.0 * s->p.collider_radius), RQ_MAX);
            memcpy(s->xs, s->x, 3 * (size_t)n * sizeof(double));
            memcpy(s->csnap, s->cs, 3 * (size_t)nc * sizeof(double));
            for (uint32_t u = 0; u < nc; ++u) {
                s->cwin[u] = s->cdisp[u] * S;
            }
            for (uint32_t i = 0; i < n; ++i) {
                s->kin[i] = s->kin_step[i] * S;
            }
            detect(g, s);
            memcpy(s->bound_frame, s->bound, (size_t)n * sizeof(double));
            memcpy(s->xs_frame, s->x, 3 * (size_t)n * sizeof(double));
        }
        if (since >= window || (clamped_last > clamp_redetect && !frame_only)) {
            /* Query radius: contact thickness plus room for the fastest vertex over the
             * window (bounds are a fraction gamma of it); fast motion shortens the window
             * so the radius stays below RQ_MAX. */
            double vmax = 0.0;
            for (uint32_t i = 0; i < n; ++i) {
                double sp = geo_len(s->v + 3 * (size_t)i);
                vmax = sp > vmax ? sp : vmax;
            }
            vmax = fmax(vmax, body_speed);
            window = frame_only ? S : (S - step < s->p.detect_window ? S - step : s->p.detect_window);
            /* Moving kinematic geometry shortens the window. Its displacement D over the window
             * is taken off the bounds of the cloth near it, so cloth pushed by it can retreat at
             * most gamma (d - D) per window: it keeps pace only while d >= D (1 + gamma) / gamma
             * (3.5 D at gamma = 0.4), else the gap closes window after window until the bound is
             * zero and the kinematic side passes through. The contact holds cloth at the contact
             * radius, so D must stay below gamma / (1 + gamma) of it. Pinned vertices (a
             * gripper's grasped patch pressed into the cloth below it) use 0.8 of that against
             * the self radius; the collider keeps its third of the collider radius (tightening
             * it changed no gripper result, where pins and fingers move together and the pin
             * rule binds first). */
            const double kin_frac = 0.8 * s->p.bound_gamma / (1.0 + s->p.bound_gamma);
            /* A frame given more substeps holds the collider near the cloth (near_collider_travel)
             * to the same rule (fast_collider_step). Every other frame keeps the third of the
             * fastest collider vertex, so it runs exactly as with fixed substeps: drops, and
             * grippers whose fingers never outrun the condition, come out bit-identical. */
            const double collider_window = raised ? fast_collider_step(&s->p) : s->p.collider_radius / 3.0;
            /* A projected collider (collider_projection) sets no bounds to keep pace with. */
            const double collider_step = s->project ? 0.0 : raised ? near_travel / S : cdisp_max;
            while (!frame_only && window > 1 &&
                   (collider_step * window > collider_window ||
                    (s->p.self_collision && pin_step_max * window > kin_frac * s->p.self_radius))) {
                window--;
            }
            double travel = 0.0;
            for (;;) {
                travel = (vmax + s->p.gravity * h * window) * h * window;
                if (window == 1 || frame_only || travel / s->p.bound_gamma + 2.0 * s->p.collider_radius <= RQ_MAX) {
                    break;
                }
                window--;
            }
            s->rq = fmin(fmax(s->p.query_radius, travel / s->p.bound_gamma + 2.0 * s->p.collider_radius), RQ_MAX);
            since = 0;
            memcpy(s->xs, s->x, 3 * (size_t)n * sizeof(double));
            if (nc > 0) {
                memcpy(s->csnap, s->cs, 3 * (size_t)nc * sizeof(double));
            }
            for (uint32_t u = 0; u < nc; ++u) {
                s->cwin[u] = s->cdisp[u] * window;
            }
            for (uint32_t i = 0; i < n; ++i) {
                s->kin[i] = s->kin_step[i] * window;
            }
            detect(g, s);
            if (split) {
                /* windowed bounds from the moving-collider pairs only */
                for (uint32_t i = 0; i < n; ++i) {
                    s->bound[i] = s->dmin_mov[i] > 0.0 ? s->p.bound_gamma * s->dmin_mov[i] : 0.0;
                }
            }
            /* Shorten the window while more than a few free vertices would outrun their
             * bounds at their current speed (the bounds stay valid: they assumed the longer
             * window). */
            while (window > 1 && !frame_only) {
                uint32_t misfits = 0;
                for (uint32_t i = 0; i < n && misfits <= clamp_redetect; ++i) {
                    double need = (fmax(geo_len(s->v + 3 * (size_t)i), body_speed) + s->p.gravity * h * window) * h * window;
                    misfits += !s->pinned[i] && need > s->bound[i];
                }
                if (misfits <= clamp_redetect) {
                    break;
                }
                window--;
            }
        }
        since++;
        predict(s, h, a1);
        solve_elastic(g, s, h);
        s->stats.contacts += solve_contacts(s);
        hold_max_distance(g, s, tethers); /* before the bounds: the cloth stays off itself */
        uint32_t clamped_now = 0;
        for (uint32_t i = 0; i < n; ++i) {
            const double *xi = s->x + 3 * (size_t)i;
            if (!s->pinned[i]) {
                const uint32_t moved = hold_to_bounds(s, i, split);
                s->stats.clamped += moved;
                clamped_now += moved;
            }
            const double *xo = s->xo + 3 * (size_t)i;
            for (int a = 0; !s->project && a < 3; ++a) { /* a projected body sets v after it moves */
                s->v[3 * (size_t)i + a] = (xi[a] - xo[a]) / h;
            }
        }
        clamped_last = clamped_now;
        if (s->project) {
            /* The body last, as the fast method meets it: cloth inside or within the contact
             * radius moves out along the nearest surface of its parts. The body cannot be held
             * back, so it has the last word over the cloth-cloth bounds (cloth the body squeezes
             * where it overlaps itself is not certified against itself there), except on the
             * vertices weft__xpbd_set_bounded_projection holds: their bounds have it. */
            s->stats.contacts += fast_collide_body(g, s);
            for (uint32_t i = 0; s->held && i < n; ++i) {
                if (s->held[i] && !s->pinned[i]) {
                    (void)hold_to_bounds(s, i, split);
                }
            }
            /* then the cloth the body pushed through the cloth goes back (weft__xpbd_set_untangle) */
            if (s->untangling) {
                s->stats.untangled += xpbd_untangle_project(&s->ut, &s->topo, g->triangles, s->x, s->w, s->p.self_radius);
            }
            for (size_t i = 0; i < 3 * (size_t)n; ++i) {
                s->v[i] = (s->x[i] - s->xo[i]) / h;
            }
        }
        if (record) {
            float *dst = s->rec + (size_t)(step + 1) * 3 * n;
            for (size_t i = 0; i < 3 * (size_t)n; ++i) {
                dst[i] = (float)s->x[i];
            }
        }
#ifdef XPBD_DEBUG_BOUNDS
        for (uint32_t i = 0; i < n; ++i) {
            for (uint32_t t = 0; t < s->nctri; ++t) {
                const uint32_t *tri = g->collider_triangles + 3 * (size_t)t;
                double dnow = sqrt(geo_point_triangle_sq(s->x + 3 * (size_t)i, s->cc + 3 * (size_t)tri[0], s->cc + 3 * (size_t)tri[1], s->cc + 3 * (size_t)tri[2], NULL));
                double dsnap = sqrt(geo_point_triangle_sq(s->xs + 3 * (size_t)i, s->csnap + 3 * (size_t)tri[0], s->csnap + 3 * (size_t)tri[1], s->csnap + 3 * (size_t)tri[2], NULL));
                double dd[3]; geo_sub(dd, s->x + 3 * (size_t)i, s->xs + 3 * (size_t)i);
                if (dnow < 1e-7) {
                    fprintf(stderr, "step %u since %u vertex %u tri %u: now %g snap %g bound %g dmin %g moved %g rq %g\n", step, since, i, t, dnow, dsnap, s->bound[i], s->dmin[i], geo_len(dd), s->rq);
                }
            }
        }
        for (uint32_t e = 0; e < s->topo.edge_count; ++e) {
            const uint32_t *a = s->topo.edges + 2 * (size_t)e;
            for (uint32_t f = 0; f < s->ctopo.edge_count; ++f) {
                const uint32_t *b = s->ctopo.edges + 2 * (size_t)f;
                double dnow = sqrt(geo_segment_segment_sq(s->x + 3 * (size_t)a[0], s->x + 3 * (size_t)a[1], s->cc + 3 * (size_t)b[0], s->cc + 3 * (size_t)b[1], NULL, NULL));
                double dsnap = sqrt(geo_segment_segment_sq(s->xs + 3 * (size_t)a[0], s->xs + 3 * (size_t)a[1], s->csnap + 3 * (size_t)b[0], s->csnap + 3 * (size_t)b[1], NULL, NULL));
                if (dnow < 1e-7) {
                    double d0[3], d1[3]; geo_sub(d0, s->x + 3 * (size_t)a[0], s->xs + 3 * (size_t)a[0]); geo_sub(d1, s->x + 3 * (size_t)a[1], s->xs + 3 * (size_t)a[1]);
                    fprintf(stderr, "EE step %u since %u edge %u-%u cedge %u-%u: now %g snap %g bounds %g %g moved %g %g rq %g\n", step, since, a[0], a[1], b[0], b[1], dnow, dsnap, s->bound[a[0]], s->bound[a[1]], geo_len(d0), geo_len(d1), s->rq);
                }
            }
        }
#endif
    }
    weft_result r = end_frame(g, s);
    s->rec_states = r == WEFT_OK && record ? S + 1 : 0;
    g->skinned_next = r == WEFT_OK ? tethers : NULL;
    return r;
}

/* ---------------------------------------------------------------------------------------- */
/* The fast method (WEFT_METHOD_XPBD_FAST): a game engine's collision projection               */

/* Cloth vertices against the collider at the substep's end (s->cc): a vertex closer than the
 * collider radius, or inside by up to FAST_DEPTH, moves out to the radius along the outward
 * direction (inside told by the nearest feature's pseudonormal), then Coulomb friction acts on
 * its motion over the substep relative to the surface point. Nothing looks between substeps:
 * a vertex the collider passed is on the wrong side and stays there. */
static uint32_t fast_collide_body(weft_garment *g, xpbd_state *s)
{
    if (s->nc == 0) {
        return 0;
    }
    weft__near_move_to(g, s->cc);
    const double r = s->p.collider_radius, mu = s->p.friction;
    uint32_t active = 0;
    for (uint32_t i = 0; i < s->n; ++i) {
        if (s->pinned[i]) {
            continue;
        }
        double *x = s->x + 3 * (size_t)i;
        weft_near_hit hit;
        const bool found = weft__near_nearest_in(g, x, r + FAST_DEPTH, s->near_seed[i], weft__part_mask(g, i), &hit);
        s->near_seed[i] = hit.tri;
        if (!found) {
            continue;
        }
        double out[3];
        bool inside;
        const bool has_out = weft__near_outward(g, x, &hit, out, &inside);
        const double dist = sqrt(hit.d2);
        if (!inside && dist < s->stats.min_collider_distance) {
            s->stats.min_collider_distance = dist;
        }
        if ((!inside && dist >= r) || !has_out) {
            continue;
        }
        const double depth = inside ? r + dist : r - dist;
        geo_axpy(x, depth, out);
        active++;
        if (mu <= 0.0) {
            continue;
        }
        const uint32_t *tri = g->collider_triangles + 3 * (size_t)hit.tri;
        double u[3];
        for (int k = 0; k < 3; ++k) {
            double c0 = 0.0;
            for (int j = 0; j < 3; ++j) {
                c0 += hit.bary[j] * s->cs[3 * (size_t)tri[j] + k];
            }
            u[k] = (x[k] - s->xo[3 * (size_t)i + k]) - (hit.point[k] - c0);
        }
        geo_axpy(u, -geo_dot(u, out), out);
        const double ut = geo_len(u), limit = mu * depth;
        if (ut > 0.0) {
            geo_axpy(x, -(ut <= limit ? 1.0 : limit / ut), u);
        }
    }
    return active;
}

typedef struct fast_self_ctx {
    xpbd_state *s;
    const uint32_t *tris;
    uint32_t v;
    uint32_t active;
} fast_self_ctx;

/* Cloth vertex v against cloth triangle t: closer than the self radius, the pair is pushed apart
 * (by inverse mass and the closest point's weights) to the radius, on the side of the triangle v
 * was on at the substep's start. */
static bool visit_fast_self(uint32_t t, void *user)
{
    fast_self_ctx *fc = user;
    xpbd_state *s = fc->s;
    const uint32_t v = fc->v, *tri = fc->tris + 3 * (size_t)t;
    if (tri[0] == v || tri[1] == v || tri[2] == v) {
        return true;
    }
    double *p = s->x + 3 * (size_t)v, *y[3], b[3];
    for (int j = 0; j < 3; ++j) {
        y[j] = s->x + 3 * (size_t)tri[j];
    }
    const double r = s->p.self_radius;
    for (int k = 0; k < 3; ++k) { /* the tree reports whole leaves: the triangle's own box first */
        if (p[k] + r < mind(y[0][k], mind(y[1][k], y[2][k])) || p[k] - r > maxd(y[0][k], maxd(y[1][k], y[2][k]))) {
            return true;
        }
    }
    const double d2 = geo_point_triangle_sq(p, y[0], y[1], y[2], b);
    if (d2 >= r * r) {
        return true;
    }
    s->stats.min_self_distance = mind(s->stats.min_self_distance, sqrt(d2));
    double e1[3], e2[3], n[3], n0[3], q[3], q0[3], d[3], d0[3];
    const double *o[3] = {s->xo + 3 * (size_t)tri[0], s->xo + 3 * (size_t)tri[1], s->xo + 3 * (size_t)tri[2]};
    geo_sub(e1, o[1], o[0]);
    geo_sub(e2, o[2], o[0]);
    geo_cross(n0, e1, e2);
    geo_sub(e1, y[1], y[0]);
    geo_sub(e2, y[2], y[0]);
    geo_cross(n, e1, e2);
    const double len = geo_len(n);
    if (!(len > 1e-30)) {
        return true;
    }
    for (int k = 0; k < 3; ++k) {
        q[k] = b[0] * y[0][k] + b[1] * y[1][k] + b[2] * y[2][k];
        q0[k] = b[0] * o[0][k] + b[1] * o[1][k] + b[2] * o[2][k];
        n[k] /= len;
    }
    geo_sub(d, p, q);
    geo_sub(d0, s->xo + 3 * (size_t)v, q0);
    const double side0 = geo_dot(d0, n0);
    const double sign = side0 > 0.0 ? 1.0 : side0 < 0.0 ? -1.0 : (geo_dot(d, n) >= 0.0 ? 1.0 : -1.0);
    const double C = sign * geo_dot(d, n) - r;
    const double wv = s->w[v], W = wv + s->w[tri[0]] * b[0] * b[0] + s->w[tri[1]] * b[1] * b[1] + s->w[tri[2]] * b[2] * b[2];
    if (C >= 0.0 || !(W > 0.0)) {
        return true;
    }
    const double dl = -C / W * sign;
    geo_axpy(p, wv * dl, n);
    for (int j = 0; j < 3; ++j) {
        geo_axpy(y[j], -s->w[tri[j]] * b[j] * dl, n);
    }
    fc->active++;
    return true;
}

/* Cloth edge fc->v against a cloth edge e2 with a higher index: closer than the self radius, the
 * closest points are pushed apart to the radius, back to the side they were on at the substep's
 * start when the edges crossed. Vertex-triangle tests alone let a fold's edges pass through
 * each other between the vertices. */
static bool visit_fast_ee(uint32_t e2, void *user)
{
    fast_self_ctx *fc = user;
    xpbd_state *s = fc->s;
    const uint32_t e1 = fc->v;
    if (e2 <= e1) {
        return true;
    }
    const uint32_t *a = s->topo.edges + 2 * (size_t)e1, *b = s->topo.edges + 2 * (size_t)e2;
    if (a[0] == b[0] || a[0] == b[1] || a[1] == b[0] || a[1] == b[1]) {
        return true;
    }
    const uint32_t idx[4] = {a[0], a[1], b[0], b[1]};
    double *y[4];
    for (int j = 0; j < 4; ++j) {
        y[j] = s->x + 3 * (size_t)idx[j];
    }
    const double r = s->p.self_radius;
    for (int k = 0; k < 3; ++k) { /* the edges' own boxes first: the tree reports whole leaves */
        if (maxd(y[0][k], y[1][k]) + r < mind(y[2][k], y[3][k]) || mind(y[0][k], y[1][k]) - r > maxd(y[2][k], y[3][k])) {
            return true;
        }
    }
    double sa, tb;
    const double d2 = geo_segment_segment_sq(y[0], y[1], y[2], y[3], &sa, &tb);
    if (d2 >= r * r) {
        return true;
    }
    s->stats.min_self_distance = mind(s->stats.min_self_distance, sqrt(d2));
    const double c[4] = {1.0 - sa, sa, -(1.0 - tb), -tb};
    double d[3] = {0, 0, 0}, d0[3] = {0, 0, 0}, n[3];
    for (int j = 0; j < 4; ++j) {
        geo_axpy(d, c[j], y[j]);
        geo_axpy(d0, c[j], s->xo + 3 * (size_t)idx[j]);
    }
    const double len = geo_len(d), len0 = geo_len(d0);
    if (geo_dot(d, d0) > 0.0 && len > 1e-12) {
        for (int k = 0; k < 3; ++k) {
            n[k] = d[k] / len;
        }
    } else if (len0 > 1e-12) { /* crossed (or touching): the side they came from */
        for (int k = 0; k < 3; ++k) {
            n[k] = d0[k] / len0;
        }
    } else {
        return true;
    }
    double W = 0.0;
    for (int j = 0; j < 4; ++j) {
        W += s->w[idx[j]] * c[j] * c[j];
    }
    const double C = geo_dot(d, n) - r;
    if (C >= 0.0 || !(W > 0.0)) {
        return true;
    }
    const double dl = -C / W;
    for (int j = 0; j < 4; ++j) {
        geo_axpy(y[j], s->w[idx[j]] * c[j] * dl, n);
    }
    fc->active++;
    return true;
}

/* A pair of cloth triangles whose leaves meet: their own boxes (padded by half the radius)
 * first, then each triangle's owned vertices against the other triangle and their owned edges
 * against each other. A vertex within the radius of a triangle lies in its owner's box, within
 * the radius of the triangle's box, so the padded boxes meet; so do two close edges' owners.
 * Neighbouring triangles are not skipped: excluding triangles that share a vertex let a sheet
 * creased over a box's edge cut itself in 74 of 90 frames (xpbd.fast's sheet_on_box), against
 * none with them. */
static void fast_tri_pair(uint32_t ta, uint32_t tb, void *user)
{
    fast_self_ctx *fc = user;
    const xpbd_state *s = fc->s;
    const double *A = s->box_tri + 6 * (size_t)ta, *B = s->box_tri + 6 * (size_t)tb;
    if (A[0] > B[3] || B[0] > A[3] || A[1] > B[4] || B[1] > A[4] || A[2] > B[5] || B[2] > A[5]) {
        return;
    }
    const uint32_t *ia = fc->tris + 3 * (size_t)ta, *ib = fc->tris + 3 * (size_t)tb;
    for (int k = 0; k < 3; ++k) {
        if (s->vert_owner[ia[k]] == ta) {
            fc->v = ia[k];
            visit_fast_self(tb, fc);
        }
        if (s->vert_owner[ib[k]] == tb) {
            fc->v = ib[k];
            visit_fast_self(ta, fc);
        }
    }
    for (int ka = 0; ka < 3; ++ka) {
        const uint32_t e1 = s->tri_edge[3 * (size_t)ta + ka];
        for (int kb = 0; kb < 3 && e1 != UINT32_MAX; ++kb) {
            const uint32_t e2 = s->tri_edge[3 * (size_t)tb + kb];
            if (e2 != UINT32_MAX) {
                fc->v = e1 < e2 ? e1 : e2;
                visit_fast_ee(e1 < e2 ? e2 : e1, fc);
            }
        }
    }
}

/* Vertex-triangle and edge-edge pairs within the self radius, from one traversal of the
 * triangle tree (built at the frame's start) against itself at the substep's positions. */
static uint32_t fast_collide_self(weft_garment *g, xpbd_state *s)
{
    if (!s->p.self_collision) {
        return 0;
    }
    const double pad = 0.5 * s->p.self_radius;
    prim_boxes(s->x, g->triangles, s->ntri, 3, s->box_tri);
    for (size_t t = 0; t < s->ntri; ++t) {
        for (int a = 0; a < 3; ++a) {
            s->box_tri[6 * t + a] -= pad;
            s->box_tri[6 * t + 3 + a] += pad;
        }
    }
    geo_bvh_refit(&s->bvh_tri, s->x, NULL, pad);
    fast_self_ctx fc = {.s = s, .tris = g->triangles};
    geo_bvh_self_pairs(&s->bvh_tri, fast_tri_pair, &fc);
    return fc.active;
}

/* A frame of the fast method: the reference's substeps and elastic projection, then the
 * collision projections, in one straight line. */
static weft_result xpbd_fast_step(weft_garment *g)
{
    xpbd_state *s = g->method_state;
    const uint32_t n = s->n, nc = s->nc, S = g->substeps;
    const double h = FRAME_DT / S;
    begin_frame(g, s, S);
    if (s->p.self_collision) {
        geo_bvh_build(&s->bvh_tri, s->x);
    }
    for (uint32_t step = 0; step < S; ++step) {
        const double a0 = (double)step / S, a1 = (double)(step + 1) / S;
        for (size_t i = 0; i < 3 * (size_t)nc; ++i) {
            s->cs[i] = s->cp[i] + a0 * (s->cn[i] - s->cp[i]);
            s->cc[i] = s->cp[i] + a1 * (s->cn[i] - s->cp[i]);
        }
        memcpy(s->xo, s->x, 3 * (size_t)n * sizeof(double));
        predict(s, h, a1);
        solve_elastic(g, s, h);
        s->stats.contacts += fast_collide_self(g, s);
        s->stats.contacts += fast_collide_body(g, s);
        for (size_t i = 0; i < 3 * (size_t)n; ++i) {
            s->v[i] = (s->x[i] - s->xo[i]) / h;
        }
    }
    return end_frame(g, s);
}

const weft_method_ops weft__xpbd_ops = {
    .name = "xpbd",
    .supports_pins = true,
    .create = xpbd_create,
    .destroy = xpbd_destroy,
    .reset = xpbd_reset,
    .step = xpbd_step,
};

const weft_method_ops weft__xpbd_fast_ops = {
    .name = "xpbd-fast",
    .supports_pins = true,
    .create = xpbd_fast_create,
    .destroy = xpbd_destroy,
    .reset = xpbd_reset,
    .step = xpbd_fast_step,
};
