/* The narrow phase against the exact GMP oracle: random queries and every degenerate class
 * (coplanar for all t, parallel edges, end-point and edge touches, zero motion, contact exactly at
 * t = 0 or t = 1, near misses at 1e-8). Zero false negatives are required; false positives are
 * counted and printed per class. */
#include "ccd/ccd_internal.h"
#include "oracle.h"
#include "test.h"

#include <gmp.h>

typedef struct tally {
    const char *name;
    int total, true_hits, fn, fp;
} tally;

static void judge(tally *t, bool vf, const double P[24])
{
    double toi = -1.0;
    int got = vf ? weft_ccd_vertex_face(P, 0.0, &toi) : weft_ccd_edge_edge(P, 0.0, &toi);
    bool truth = vf ? oracle_vf(P) : oracle_ee(P);
    t->total++;
    t->true_hits += truth;
    if (truth && !got) {
        t->fn++;
        fprintf(stderr, "false negative (%s, %s):", t->name, vf ? "vf" : "ee");
        for (int i = 0; i < 24; ++i) {
            fprintf(stderr, " %.17g", P[i]);
        }
        fputc('\n', stderr);
    }
    if (got && !truth) {
        t->fp++;
    }
    CHECK_MSG(!got || (toi >= 0.0 && toi <= 1.0), "toi %g outside [0, 1]", toi);
}

static void finish(const tally *t)
{
    printf("%-28s %5d queries %5d true hits  FN %d  FP %d (%.2f%% of negatives)\n", t->name, t->total, t->true_hits,
           t->fn, t->fp, t->total > t->true_hits ? 100.0 * t->fp / (t->total - t->true_hits) : 0.0);
    CHECK_MSG(t->fn == 0, "%s: %d false negatives", t->name, t->fn);
}

/* Query counts: the defaults keep the test short; WEFT_CCD_ORACLE_SCALE=N multiplies them (the
 * figures in docs/CCD.md use N = 10). */
static int count(int n)
{
    const char *e = getenv("WEFT_CCD_ORACLE_SCALE");
    int k = e ? atoi(e) : 1;
    return n * (k > 0 ? k : 1);
}

static double rnd(test_rng *r, double lo, double hi) { return lo + (hi - lo) * (double)(test_rng_u32(r) & 0xffffff) / 16777216.0; }

/* Small integers keep degenerate constructions exact. */
static double irnd(test_rng *r, int lo, int hi) { return (double)(lo + (int)(test_rng_u32(r) % (unsigned)(hi - lo + 1))); }

static void random_queries(void)
{
    test_rng r = {0x1234567u};
    tally tv = {.name = "random vf"}, te = {.name = "random ee"};
    for (int n = 0; n < count(900); ++n) {
        double P[24];
        for (int i = 0; i < 12; ++i) {
            P[i] = rnd(&r, -1, 1);
            P[12 + i] = P[i] + rnd(&r, -1, 1);
        }
        judge(&tv, true, P);
        judge(&te, false, P);
    }
    finish(&tv);
    finish(&te);
}

/* A contact at t* built in double (then near the exact boundary), mixed with misses. */
static void constructed_contacts(void)
{
    test_rng r = {0xabcdefu};
    tally tv = {.name = "constructed vf"}, te = {.name = "constructed ee"};
    for (int n = 0; n < count(600); ++n) {
        double P[24];
        for (int i = 0; i < 12; ++i) {
            P[i] = rnd(&r, -1, 1);
            P[12 + i] = P[i] + rnd(&r, -0.5, 0.5);
        }
        double ts = rnd(&r, 0, 1);
        double u = rnd(&r, -0.1, 1), v = rnd(&r, -0.1, 1 - u);
        /* VF: put the vertex on the triangle (or just outside) at ts. */
        double Q[24];
        memcpy(Q, P, sizeof Q);
        for (int k = 0; k < 3; ++k) {
            double a = P[3 + k] + ts * (P[15 + k] - P[3 + k]);
            double b = P[6 + k] + ts * (P[18 + k] - P[6 + k]);
            double c = P[9 + k] + ts * (P[21 + k] - P[9 + k]);
            double target = a + u * (b - a) + v * (c - a);
            Q[12 + k] = ts > 0 ? Q[k] + (target - Q[k]) / ts : target;
        }
        judge(&tv, true, Q);
        /* EE: make edge a pass through a point of edge b at ts. */
        memcpy(Q, P, sizeof Q);
        double s = rnd(&r, -0.05, 1.05), w = rnd(&r, 0, 1);
        for (int k = 0; k < 3; ++k) {
            double b0 = P[6 + k] + ts * (P[18 + k] - P[6 + k]);
            double b1 = P[9 + k] + ts * (P[21 + k] - P[9 + k]);
            double a1 = P[3 + k] + ts * (P[15 + k] - P[3 + k]);
            double target = b0 + s * (b1 - b0);
            /* a0(ts) chosen so that target = a0 + w (a1 - a0). */
            double a0 = w < 1 ? (target - w * a1) / (1 - w) : target;
            Q[12 + k] = ts > 0 ? Q[k] + (a0 - Q[k]) / ts : a0;
        }
        judge(&te, false, Q);
    }
    finish(&tv);
    finish(&te);
}

static void coplanar_for_all_t(void)
{
    test_rng r = {0x777u};
    tally tv = {.name = "coplanar all t vf"}, te = {.name = "coplanar all t ee"};
    for (int n = 0; n < count(400); ++n) {
        double P[24];
        for (int i = 0; i < 8; ++i) {
            P[3 * i + 0] = irnd(&r, -6, 6);
            P[3 * i + 1] = irnd(&r, -6, 6);
            P[3 * i + 2] = 0.0;
        }
        judge(&tv, true, P);
        judge(&te, false, P);
        /* A tilted common plane z = x/2 + y/4 (exact in binary). */
        for (int i = 0; i < 8; ++i) {
            P[3 * i + 2] = P[3 * i] / 2 + P[3 * i + 1] / 4;
        }
        judge(&tv, true, P);
        judge(&te, false, P);
    }
    finish(&tv);
    finish(&te);
}

static void parallel_edges(void)
{
    test_rng r = {0x999u};
    tally te = {.name = "parallel edges"};
    for (int n = 0; n < count(500); ++n) {
        double P[24];
        double d[3] = {irnd(&r, -3, 3), irnd(&r, -3, 3), irnd(&r, -3, 3)};
        double e[3] = {irnd(&r, -3, 3), irnd(&r, -3, 3), irnd(&r, -3, 3)};
        for (int f = 0; f < 2; ++f) {
            double *F = P + 12 * f;
            double la = irnd(&r, 1, 3), lb = irnd(&r, 1, 3);
            const double *dir = (n % 2 == 0 || f == 0) ? d : e; /* parallel at both ends, or only at t = 0 */
            for (int k = 0; k < 3; ++k) {
                F[k] = irnd(&r, -2, 2);
                F[3 + k] = F[k] + la * dir[k];
                F[6 + k] = (n % 3 == 0 ? F[k] : irnd(&r, -2, 2)); /* often collinear */
                F[9 + k] = F[6 + k] + lb * dir[k];
            }
        }
        judge(&te, false, P);
    }
    finish(&te);
}

/* Static triangle (0,0,0) (4,0,0) (0,4,0); the vertex crosses z = 0 at t = 1/2 at an integer
 * point: inside, on an edge, on a corner, or just outside. */
static void touching(void)
{
    test_rng r = {0x4242u};
    tally tv = {.name = "edge/corner touches vf"}, te = {.name = "end-point touches ee"};
    for (int n = 0; n < count(400); ++n) {
        double cx = irnd(&r, -1, 5), cy = irnd(&r, -1, 5);
        double dx = irnd(&r, -2, 2), dy = irnd(&r, -2, 2), h = irnd(&r, 1, 3);
        double P[24] = {cx - dx, cy - dy, h, 0, 0, 0, 4, 0, 0, 0, 4, 0,
                        cx + dx, cy + dy, -h, 0, 0, 0, 4, 0, 0, 0, 4, 0};
        judge(&tv, true, P);
        /* Edge a moves down through z = 0 while edge b lies on the x axis [0, 4]: a's end point
         * touches b's end point or interior. */
        double Q[24] = {cx - dx, cy - dy, h, cx - dx + 2, cy - dy + 1, h, 0, 0, 0, 4, 0, 0,
                        cx + dx, cy + dy, -h, cx + dx + 2, cy + dy + 1, -h, 0, 0, 0, 4, 0, 0};
        Q[1] = 0;
        Q[13] = 0; /* end point a0 stays on the line y = 0 */
        judge(&te, false, Q);
    }
    finish(&tv);
    finish(&te);
}

static void zero_motion_and_endpoints(void)
{
    test_rng r = {0x5151u};
    tally tz = {.name = "zero motion vf/ee"}, t01 = {.name = "contact at t=0 or t=1"};
    for (int n = 0; n < count(400); ++n) {
        double P[24];
        for (int i = 0; i < 12; ++i) {
            P[i] = irnd(&r, -3, 3);
            P[12 + i] = P[i];
        }
        if (n % 2) { /* put the vertex on the triangle's plane, inside or outside */
            double u = irnd(&r, 0, 2) / 4, v = irnd(&r, 0, 2) / 4;
            for (int k = 0; k < 3; ++k) {
                P[k] = P[3 + k] + u * (P[6 + k] - P[3 + k]) + v * (P[9 + k] - P[3 + k]);
                P[12 + k] = P[k];
            }
        }
        judge(&tz, true, P);
        judge(&tz, false, P);
        /* Contact exactly at t = 0 (or t = 1): the vertex on the triangle, then moving away. */
        double Q[24];
        memcpy(Q, P, sizeof Q);
        double u = irnd(&r, 0, 4) / 4, v = irnd(&r, 0, 4 - (int)(u * 4)) / 4;
        int at = n % 2 ? 12 : 0;
        for (int k = 0; k < 3; ++k) {
            Q[at + k] = Q[at + 3 + k] + u * (Q[at + 6 + k] - Q[at + 3 + k]) + v * (Q[at + 9 + k] - Q[at + 3 + k]);
        }
        for (int k = 0; k < 3; ++k) {
            Q[12 - at + k] = Q[at + k] + irnd(&r, -2, 2);
        }
        judge(&t01, true, Q);
        judge(&t01, false, Q);
    }
    finish(&tz);
    finish(&t01);
}

/* Contacts shifted by +-1e-8 along the normal: hits at -1e-8 must be found; misses at +1e-8 are
 * within eta and so count as (expected) false positives. */
static void near_misses(void)
{
    test_rng r = {0x8888u};
    tally tv = {.name = "near miss 1e-8 vf"}, te = {.name = "near miss 1e-8 ee"};
    for (int n = 0; n < count(400); ++n) {
        double off = (n % 2 ? 1e-8 : -1e-8);
        double u = rnd(&r, 0, 0.5), v = rnd(&r, 0, 0.5);
        /* Vertex grazes the static triangle z = 0 from above: lowest point z = off at t = 1. */
        double P[24] = {u, v, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, u + rnd(&r, -0.2, 0.2), v + rnd(&r, -0.2, 0.2), off,
                        0, 0, 0, 1, 0, 0, 0, 1, 0};
        judge(&tv, true, P);
        /* Vertex slides parallel to the plane at height off. */
        double Q[24] = {u - 1, v, off, 0, 0, 0, 1, 0, 0, 0, 1, 0, u + 1, v, off, 0, 0, 0, 1, 0, 0, 0, 1, 0};
        judge(&tv, true, Q);
        /* Edges: a comes down onto the crossing edge b and stops at height off (a hit for off < 0). */
        double E[24] = {-1, u, 1, 1, u, 1, v, -1, 0, v, 1, 0, -1, u, off, 1, u, off, v, -1, 0, v, 1, 0};
        judge(&te, false, E);
    }
    finish(&tv);
    finish(&te);
}

/* The coplanarity cubic has a double root at t = 1/2 (the triangle turns while the vertex passes
 * tangentially), with the contact inside, on the boundary or just missed by delta. */
static void tangent_double_roots(void)
{
    test_rng r = {0x3131u};
    tally tv = {.name = "tangent double root vf"};
    static const double deltas[5] = {0.0, 0.0, 1e-9, -1e-9, 0x1p-30};
    for (int n = 0; n < count(500); ++n) {
        double k = irnd(&r, -8, 8) / 4, px = irnd(&r, -2, 6) / 4, cx = irnd(&r, 0, 2) / 4;
        double alpha = -irnd(&r, 1, 4) / 2, h = irnd(&r, 1, 3);
        double dl = deltas[n % 5];
        double pz = -h * alpha / 2;
        /* a, b static on the x axis; c(t) = (cx, 1 - 2t, 2 t h); p_y(t) = alpha (t - 1/2) + delta. */
        double P[24] = {px, -alpha / 2 + dl, pz - k / 2, 0, 0, 0, 1, 0, 0, cx, 1, 0,
                        px, alpha / 2 + dl, pz + k / 2, 0, 0, 0, 1, 0, 0, cx, -1, 2 * h};
        judge(&tv, true, P);
    }
    finish(&tv);
}

/* Edge b nearly parallel to edge a (angles 2^-10 .. 2^-40) crossing a's line at, just inside or
 * just beyond a's end point while a sweeps through b's plane: ill-conditioned closest points. The
 * misses pass within about 2^-30 * angle of the end point, far inside eta: reported hits there are
 * the expected false positives of the minimum separation. */
static void nearly_parallel_edges(void)
{
    test_rng r = {0x7171u};
    tally te = {.name = "nearly parallel edges"};
    static const double ends[4] = {0.3, 1.0, 1.0 - 0x1p-30, 1.0 + 0x1p-30};
    for (int n = 0; n < count(500); ++n) {
        double ang = ldexp(1.0, -(10 + (int)(test_rng_u32(&r) % 31)));
        double off = n % 3 == 0 ? 0.0 : ldexp(n % 3 == 1 ? 1.0 : -1.0, -(20 + (int)(test_rng_u32(&r) % 31)));
        double L = 0.5 + rnd(&r, 0, 1), x = ends[n % 4];
        double P[24] = {-1, 0, 1,  1, 0, 1,  x - L, -L * ang, off, x + L, L * ang, off,
                        -1, 0, -1, 1, 0, -1, x - L, -L * ang, off, x + L, L * ang, off};
        judge(&te, false, P);
    }
    finish(&te);
}

/* Triangles collapsing to a segment or a point during the motion, and edges of length zero. */
static void zero_area_and_zero_length(void)
{
    test_rng r = {0x2222u};
    tally tv = {.name = "zero-area triangles vf"}, te = {.name = "zero-length edges ee"};
    for (int n = 0; n < count(400); ++n) {
        double P[24];
        for (int i = 0; i < 24; ++i) {
            P[i] = irnd(&r, -3, 3);
        }
        for (int f = 0; f < 2; ++f) { /* c on line ab (or equal to a) at t = 0 and t = 1 */
            double *F = P + 12 * f;
            double s = irnd(&r, -2, 4) / 2;
            for (int k = 0; k < 3; ++k) {
                F[9 + k] = (n % 4 == 0) ? F[3 + k] : F[3 + k] + s * (F[6 + k] - F[3 + k]);
            }
        }
        if (n % 3 == 0) { /* vertex through the degenerate triangle's segment at t = 1/2 */
            for (int k = 0; k < 3; ++k) {
                double mid = 0.25 * (P[3 + k] + P[15 + k]) + 0.25 * (P[6 + k] + P[18 + k]);
                P[12 + k] = 2 * mid - P[k];
            }
        }
        judge(&tv, true, P);
        for (int k = 0; k < 3; ++k) { /* edge a collapsed to a point */
            P[3 + k] = P[k];
            P[15 + k] = P[12 + k];
        }
        judge(&te, false, P);
    }
    finish(&tv);
    finish(&te);
}

/* The same constructions far from the origin and at small and large scales. */
static void scaled_and_translated(void)
{
    test_rng r = {0x6161u};
    tally tv = {.name = "scaled/translated vf"}, te = {.name = "scaled/translated ee"};
    static const double scales[4] = {1e-4, 1e3, 1.0, 1.0};
    static const double shifts[4] = {0.0, 0.0, 1e4, -3e5};
    for (int n = 0; n < count(500); ++n) {
        double sc = scales[n % 4], sh = shifts[n % 4];
        double P[24];
        for (int i = 0; i < 12; ++i) {
            P[i] = rnd(&r, -1, 1);
            P[12 + i] = P[i] + rnd(&r, -1, 1);
        }
        if (n % 2) { /* force a crossing through the triangle / edge interior at t = 1/2 */
            for (int k = 0; k < 3; ++k) {
                double a = 0.5 * (P[3 + k] + P[15 + k]), b = 0.5 * (P[6 + k] + P[18 + k]);
                double c = 0.5 * (P[9 + k] + P[21 + k]);
                double target = (a + b + c) / 3;
                P[12 + k] = 2 * target - P[k];
            }
        }
        for (int i = 0; i < 24; ++i) {
            P[i] = P[i] * sc + sh;
        }
        judge(&tv, true, P);
        judge(&te, false, P);
    }
    finish(&tv);
    finish(&te);
}

static int exact_sign_det3(const double *a, const double *b, const double *c, const double *d)
{
    mpq_t m[3][3], t, u, det;
    mpq_inits(t, u, det, NULL);
    const double *q[3] = {b, c, d};
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            mpq_init(m[i][k]);
            mpq_set_d(t, q[i][k]);
            mpq_set_d(u, a[k]);
            mpq_sub(m[i][k], t, u);
        }
    }
    for (int k = 0; k < 3; ++k) { /* det = sum_k m0k * cofactor */
        int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
        mpq_mul(t, m[1][k1], m[2][k2]);
        mpq_mul(u, m[1][k2], m[2][k1]);
        mpq_sub(t, t, u);
        mpq_mul(t, t, m[0][k]);
        mpq_add(det, det, t);
    }
    int s = mpq_sgn(det);
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            mpq_clear(m[i][k]);
        }
    }
    mpq_clears(t, u, det, NULL);
    return s;
}

/* orient3d / orient2d on nearly and exactly coplanar points against exact rational determinants. */
static void exact_predicates(void)
{
    test_rng r = {0x5eedu};
    int mismatches = 0, zeros = 0, n = count(3000);
    for (int i = 0; i < n; ++i) {
        double a[3], b[3], c[3], d[3];
        for (int k = 0; k < 3; ++k) {
            a[k] = rnd(&r, -1, 1) * (i % 3 == 0 ? 1e3 : 1.0);
            b[k] = rnd(&r, -1, 1);
            c[k] = rnd(&r, -1, 1);
        }
        double s = rnd(&r, -1, 2), u = rnd(&r, -1, 2);
        for (int k = 0; k < 3; ++k) { /* on the plane up to rounding, sometimes exactly */
            d[k] = (i % 4 == 0) ? b[k] + (c[k] - b[k]) * 0.5 : a[k] + s * (b[k] - a[k]) + u * (c[k] - a[k]);
        }
        if (i % 4 == 0) {
            for (int k = 0; k < 3; ++k) {
                a[k] = 2 * b[k] - c[k]; /* a, b, c, d collinear-ish: many exact zeros */
            }
        }
        int e = exact_sign_det3(a, b, c, d);
        zeros += e == 0;
        mismatches += ccd_orient3d(a, b, c, d) != e;
        /* orient2d(a, b, d) in xy is det(b - a, d - a, e_z) with everything lifted to z = 0. */
        double pa[3] = {a[0], a[1], 0}, pb[3] = {b[0], b[1], 0}, pd[3] = {d[0], d[1], 0}, pz[3] = {a[0], a[1], 1};
        mismatches += ccd_orient2d(a, b, d, 0, 1) != exact_sign_det3(pa, pb, pd, pz);
    }
    printf("exact predicates: %d orientation cases (%d exactly zero), %d mismatches\n", n, zeros, mismatches);
    CHECK_EQ_INT(mismatches, 0);
}

static void non_finite_is_conservative(void)
{
    double P[24] = {0};
    P[5] = NAN;
    double toi = -1;
    CHECK_EQ_INT(weft_ccd_vertex_face(P, 0, &toi), 1);
    CHECK(toi == 0.0);
    P[5] = INFINITY;
    CHECK_EQ_INT(weft_ccd_edge_edge(P, 0, &toi), 1);
    CHECK_EQ_INT(weft_ccd_vertex_face(NULL, 0, &toi), 0);
}

TEST_MAIN(TEST_CASE(random_queries), TEST_CASE(constructed_contacts), TEST_CASE(coplanar_for_all_t),
          TEST_CASE(parallel_edges), TEST_CASE(touching), TEST_CASE(zero_motion_and_endpoints),
          TEST_CASE(near_misses), TEST_CASE(tangent_double_roots), TEST_CASE(nearly_parallel_edges),
          TEST_CASE(zero_area_and_zero_length),
          TEST_CASE(scaled_and_translated), TEST_CASE(exact_predicates), TEST_CASE(non_finite_is_conservative))
