/* Exact geometric predicates for the discrete intersection checks: orient2d / orient3d with a
 * floating-point filter and an exact fallback in expansion arithmetic (sums of non-overlapping
 * doubles, after Shewchuk's "Adaptive precision floating-point arithmetic"), and the closed
 * triangle–triangle and segment–triangle tests built only from their signs.
 * Exact as long as no intermediate product overflows or underflows (|coordinates| within about
 * 1e-90 .. 1e90), which covers every float input. */
#include "ccd/ccd_internal.h"

#include <math.h>

/* ---- expansion arithmetic --------------------------------------------------------------- */

static inline void two_sum(double a, double b, double *x, double *y)
{
    double s = a + b;
    double bv = s - a;
    double av = s - bv;
    *x = s;
    *y = (a - av) + (b - bv);
}

static inline void two_diff(double a, double b, double *x, double *y)
{
    double s = a - b;
    double bv = a - s;
    double av = s + bv;
    *x = s;
    *y = (a - av) + (bv - b);
}

static inline void two_prod(double a, double b, double *x, double *y)
{
    double p = a * b;
    *x = p;
    *y = fma(a, b, -p); /* exact rounding error of the product */
}

/* h = e + b (zero components removed); h has room for elen + 1. */
static int grow(int elen, const double *e, double b, double *h)
{
    double q = b;
    int n = 0;
    for (int i = 0; i < elen; ++i) {
        double s, r;
        two_sum(q, e[i], &s, &r);
        q = s;
        if (r != 0.0) {
            h[n++] = r;
        }
    }
    if (q != 0.0 || n == 0) {
        h[n++] = q;
    }
    return n;
}

/* h = e + f; h has room for elen + flen; tmp the same. */
static int sum(int elen, const double *e, int flen, const double *f, double *h, double *tmp)
{
    int n = elen;
    for (int i = 0; i < elen; ++i) {
        h[i] = e[i];
    }
    for (int j = 0; j < flen; ++j) {
        n = grow(n, h, f[j], tmp);
        for (int i = 0; i < n; ++i) {
            h[i] = tmp[i];
        }
    }
    return n;
}

/* h = e * b; h has room for 2 elen (elen <= 32). */
static int scale(int elen, const double *e, double b, double *h)
{
    double cur[72], tmp[72];
    int n = 1;
    cur[0] = 0.0;
    for (int i = 0; i < elen; ++i) {
        double p, r;
        two_prod(e[i], b, &p, &r);
        n = grow(n, cur, r, tmp);
        n = grow(n, tmp, p, cur);
    }
    for (int k = 0; k < n; ++k) {
        h[k] = cur[k];
    }
    return n;
}

/* h = e * f (elen <= 32, elen * flen <= 64); h has room for 2 elen flen. */
static int mul(int elen, const double *e, int flen, const double *f, double *h)
{
    double part[64], acc[128], tmp[128];
    int n = 1;
    acc[0] = 0.0;
    for (int j = 0; j < flen; ++j) {
        int pn = scale(elen, e, f[j], part);
        n = sum(n, acc, pn, part, h, tmp);
        for (int i = 0; i < n; ++i) {
            acc[i] = h[i];
        }
    }
    for (int i = 0; i < n; ++i) {
        h[i] = acc[i];
    }
    return n;
}

static int expansion_sign(int n, const double *e)
{
    /* Components are non-overlapping and in increasing magnitude: the last non-zero one decides. */
    for (int i = n - 1; i >= 0; --i) {
        if (e[i] != 0.0) {
            return e[i] > 0.0 ? 1 : -1;
        }
    }
    return 0;
}

/* ---- orient2d / orient3d ----------------------------------------------------------------- */

static int sign_of(double x) { return x > 0.0 ? 1 : (x < 0.0 ? -1 : 0); }

int ccd_orient2d(const double a[3], const double b[3], const double c[3], int i, int j)
{
    double l = (b[i] - a[i]) * (c[j] - a[j]);
    double r = (b[j] - a[j]) * (c[i] - a[i]);
    double det = l - r;
    double bound = 4e-16 * (fabs(l) + fabs(r));
    if (fabs(det) > bound) {
        return sign_of(det);
    }
    /* Exactly zero when the three points share one projected coordinate (a zero column): the
     * common degenerate case of flat sheets and floors in axis planes, decided without the
     * expansion arithmetic. */
    if ((a[i] == b[i] && a[i] == c[i]) || (a[j] == b[j] && a[j] == c[j])) {
        return 0;
    }
    double ux[2], uy[2], vx[2], vy[2];
    two_diff(b[i], a[i], &ux[1], &ux[0]);
    two_diff(b[j], a[j], &uy[1], &uy[0]);
    two_diff(c[i], a[i], &vx[1], &vx[0]);
    two_diff(c[j], a[j], &vy[1], &vy[0]);
    double p[16], q[16], h[32], tmp[32];
    int pn = mul(2, ux, 2, vy, p);
    int qn = mul(2, uy, 2, vx, q);
    for (int k = 0; k < qn; ++k) {
        q[k] = -q[k];
    }
    int hn = sum(pn, p, qn, q, h, tmp);
    return expansion_sign(hn, h);
}

int ccd_orient3d(const double a[3], const double b[3], const double c[3], const double d[3])
{
    double u[3], v[3], w[3];
    for (int k = 0; k < 3; ++k) {
        u[k] = b[k] - a[k];
        v[k] = c[k] - a[k];
        w[k] = d[k] - a[k];
    }
    double m0 = v[1] * w[2] - v[2] * w[1];
    double m1 = v[2] * w[0] - v[0] * w[2];
    double m2 = v[0] * w[1] - v[1] * w[0];
    double det = u[0] * m0 + u[1] * m1 + u[2] * m2;
    double perm = fabs(u[0]) * (fabs(v[1] * w[2]) + fabs(v[2] * w[1])) +
                  fabs(u[1]) * (fabs(v[2] * w[0]) + fabs(v[0] * w[2])) +
                  fabs(u[2]) * (fabs(v[0] * w[1]) + fabs(v[1] * w[0]));
    /* Shewchuk's first-stage bound is (7 + 56 eps) eps * perm = 7.8e-16 perm; 2e-15 leaves margin. */
    if (fabs(det) > 2e-15 * perm) {
        return sign_of(det);
    }
    /* Exactly zero when the four points share one coordinate (a zero column), as above. */
    for (int k = 0; k < 3; ++k) {
        if (a[k] == b[k] && a[k] == c[k] && a[k] == d[k]) {
            return 0;
        }
    }
    double U[3][2], V[3][2], W[3][2];
    for (int k = 0; k < 3; ++k) {
        two_diff(b[k], a[k], &U[k][1], &U[k][0]);
        two_diff(c[k], a[k], &V[k][1], &V[k][0]);
        two_diff(d[k], a[k], &W[k][1], &W[k][0]);
    }
    double total[256], next[256], scratch[256];
    int tn = 1;
    total[0] = 0.0;
    for (int k = 0; k < 3; ++k) {
        int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
        double p[8], q[8], m[16], t1[16], term[64];
        int pn = mul(2, V[k1], 2, W[k2], p);
        int qn = mul(2, V[k2], 2, W[k1], q);
        for (int i = 0; i < qn; ++i) {
            q[i] = -q[i];
        }
        int mn = sum(pn, p, qn, q, m, t1);
        int termn = mul(mn, m, 2, U[k], term);
        tn = sum(tn, total, termn, term, next, scratch);
        for (int i = 0; i < tn; ++i) {
            total[i] = next[i];
        }
    }
    return expansion_sign(tn, total);
}

/* ---- closed segment / triangle tests ---------------------------------------------------- */

static bool collinear3(const double *a, const double *b, const double *c)
{
    return ccd_orient2d(a, b, c, 0, 1) == 0 && ccd_orient2d(a, b, c, 1, 2) == 0 && ccd_orient2d(a, b, c, 0, 2) == 0;
}

static bool between(double x, double a, double b) { return (a <= x && x <= b) || (b <= x && x <= a); }

/* Closed 2D segments ab, cd in the (i, j) projection. */
static bool seg_seg_2d(const double *a, const double *b, const double *c, const double *d, int i, int j)
{
    int d1 = ccd_orient2d(c, d, a, i, j), d2 = ccd_orient2d(c, d, b, i, j);
    int d3 = ccd_orient2d(a, b, c, i, j), d4 = ccd_orient2d(a, b, d, i, j);
    if (d1 * d2 < 0 && d3 * d4 < 0) {
        return true;
    }
    if (d1 == 0 && between(a[i], c[i], d[i]) && between(a[j], c[j], d[j])) {
        return true;
    }
    if (d2 == 0 && between(b[i], c[i], d[i]) && between(b[j], c[j], d[j])) {
        return true;
    }
    if (d3 == 0 && between(c[i], a[i], b[i]) && between(c[j], a[j], b[j])) {
        return true;
    }
    if (d4 == 0 && between(d[i], a[i], b[i]) && between(d[j], a[j], b[j])) {
        return true;
    }
    return false;
}

/* Closed 2D point-in-triangle (triangle non-degenerate in this projection). */
static bool point_in_tri_2d(const double *p, const double *a, const double *b, const double *c, int i, int j)
{
    int o1 = ccd_orient2d(a, b, p, i, j), o2 = ccd_orient2d(b, c, p, i, j), o3 = ccd_orient2d(c, a, p, i, j);
    return (o1 >= 0 && o2 >= 0 && o3 >= 0) || (o1 <= 0 && o2 <= 0 && o3 <= 0);
}

/* A projection (i, j) in which the non-degenerate triangle abc stays non-degenerate. */
static void projection_of(const double *a, const double *b, const double *c, int *pi, int *pj)
{
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {fabs(u[1] * v[2] - u[2] * v[1]), fabs(u[2] * v[0] - u[0] * v[2]), fabs(u[0] * v[1] - u[1] * v[0])};
    int order[3] = {0, 1, 2};
    for (int x = 0; x < 2; ++x) {
        for (int y = 0; y < 2 - x; ++y) {
            if (n[order[y]] < n[order[y + 1]]) {
                int t = order[y];
                order[y] = order[y + 1];
                order[y + 1] = t;
            }
        }
    }
    for (int k = 0; k < 3; ++k) {
        int drop = order[k];
        int i = (drop + 1) % 3, j = (drop + 2) % 3;
        if (ccd_orient2d(a, b, c, i, j) != 0) {
            *pi = i;
            *pj = j;
            return;
        }
    }
    *pi = 0; /* unreachable for a non-degenerate triangle */
    *pj = 1;
}

/* Closed segment pq against closed non-degenerate triangle abc. */
static bool seg_tri(const double *p, const double *q, const double *a, const double *b, const double *c)
{
    int sp = ccd_orient3d(a, b, c, p), sq = ccd_orient3d(a, b, c, q);
    if (sp * sq > 0) {
        return false;
    }
    if (sp == 0 && sq == 0) {
        int i, j;
        projection_of(a, b, c, &i, &j);
        return point_in_tri_2d(p, a, b, c, i, j) || point_in_tri_2d(q, a, b, c, i, j) ||
               seg_seg_2d(p, q, a, b, i, j) || seg_seg_2d(p, q, b, c, i, j) || seg_seg_2d(p, q, c, a, i, j);
    }
    int o1 = ccd_orient3d(p, q, a, b), o2 = ccd_orient3d(p, q, b, c), o3 = ccd_orient3d(p, q, c, a);
    return (o1 >= 0 && o2 >= 0 && o3 >= 0) || (o1 <= 0 && o2 <= 0 && o3 <= 0);
}

/* Closed 3D segments: coplanar and intersecting in all three coordinate projections (one of which
 * is injective on their common line or plane). */
static bool seg_seg_3d(const double *a, const double *b, const double *c, const double *d)
{
    if (ccd_orient3d(a, b, c, d) != 0) {
        return false;
    }
    return seg_seg_2d(a, b, c, d, 0, 1) && seg_seg_2d(a, b, c, d, 1, 2) && seg_seg_2d(a, b, c, d, 0, 2);
}

bool ccd_tri_tri(const double *a0, const double *a1, const double *a2, const double *b0, const double *b1,
                 const double *b2)
{
    const double *A[3] = {a0, a1, a2}, *B[3] = {b0, b1, b2};
    bool da = collinear3(a0, a1, a2), db = collinear3(b0, b1, b2);
    if (da && db) {
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                if (seg_seg_3d(A[i], A[(i + 1) % 3], B[j], B[(j + 1) % 3])) {
                    return true;
                }
            }
        }
        return false;
    }
    if (da || db) {
        const double *const *S = da ? A : B;
        const double *const *T = da ? B : A;
        for (int i = 0; i < 3; ++i) {
            if (seg_tri(S[i], S[(i + 1) % 3], T[0], T[1], T[2])) {
                return true;
            }
        }
        return false;
    }
    /* Separating planes. */
    int s0 = ccd_orient3d(a0, a1, a2, b0), s1 = ccd_orient3d(a0, a1, a2, b1), s2 = ccd_orient3d(a0, a1, a2, b2);
    if ((s0 > 0 && s1 > 0 && s2 > 0) || (s0 < 0 && s1 < 0 && s2 < 0)) {
        return false;
    }
    int r0 = ccd_orient3d(b0, b1, b2, a0), r1 = ccd_orient3d(b0, b1, b2, a1), r2 = ccd_orient3d(b0, b1, b2, a2);
    if ((r0 > 0 && r1 > 0 && r2 > 0) || (r0 < 0 && r1 < 0 && r2 < 0)) {
        return false;
    }
    if (s0 == 0 && s1 == 0 && s2 == 0) {
        int i, j;
        projection_of(a0, a1, a2, &i, &j);
        for (int x = 0; x < 3; ++x) {
            for (int y = 0; y < 3; ++y) {
                if (seg_seg_2d(A[x], A[(x + 1) % 3], B[y], B[(y + 1) % 3], i, j)) {
                    return true;
                }
            }
        }
        return point_in_tri_2d(b0, a0, a1, a2, i, j) || point_in_tri_2d(a0, b0, b1, b2, i, j);
    }
    /* Non-coplanar: the intersection, if any, is a segment whose end points lie on an edge of one
     * triangle inside the other. */
    for (int x = 0; x < 3; ++x) {
        if (seg_tri(A[x], A[(x + 1) % 3], b0, b1, b2) || seg_tri(B[x], B[(x + 1) % 3], a0, a1, a2)) {
            return true;
        }
    }
    return false;
}

int ccd_segment_crosses_triangle_strict(const double p[3], const double q[3], const double a[3], const double b[3],
                                        const double c[3])
{
    int sp = ccd_orient3d(a, b, c, p), sq = ccd_orient3d(a, b, c, q);
    if (sp * sq > 0) {
        return 0;
    }
    int o1 = ccd_orient3d(p, q, a, b), o2 = ccd_orient3d(p, q, b, c), o3 = ccd_orient3d(p, q, c, a);
    bool pos = o1 > 0 || o2 > 0 || o3 > 0, neg = o1 < 0 || o2 < 0 || o3 < 0;
    if (pos && neg) {
        return 0; /* the line misses the closed triangle */
    }
    if (sp == 0 || sq == 0 || o1 == 0 || o2 == 0 || o3 == 0) {
        return -1; /* touches the plane at an end point, or an edge or vertex of the triangle */
    }
    return 1;
}

int weft_ccd_triangles_intersect(const double a[9], const double b[9])
{
    if (!a || !b) {
        return 0;
    }
    for (int i = 0; i < 9; ++i) {
        if (!isfinite(a[i]) || !isfinite(b[i])) {
            return 1;
        }
    }
    return ccd_tri_tri(a, a + 3, a + 6, b, b + 3, b + 6) ? 1 : 0;
}
