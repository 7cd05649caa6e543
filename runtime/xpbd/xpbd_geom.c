/* Distance, intersection and conservative-advancement kernels in double precision. */
#include "xpbd/xpbd.h"

#include <math.h>

double xg_point_triangle_sq(const double *p, const double *a, const double *b, const double *c, double bary[3])
{
    /* Voronoi-region walk over the triangle's vertices, edges and face. */
    double ab[3], ac[3], ap[3], bp[3], cp[3], q[3];
    xv_sub(ab, b, a);
    xv_sub(ac, c, a);
    xv_sub(ap, p, a);
    double d1 = xv_dot(ab, ap), d2 = xv_dot(ac, ap);
    double u, v, w;
    if (d1 <= 0.0 && d2 <= 0.0) {
        u = 1.0, v = 0.0, w = 0.0;
        goto done;
    }
    xv_sub(bp, p, b);
    double d3 = xv_dot(ab, bp), d4 = xv_dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) {
        u = 0.0, v = 1.0, w = 0.0;
        goto done;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        v = d1 / (d1 - d3);
        u = 1.0 - v, w = 0.0;
        goto done;
    }
    xv_sub(cp, p, c);
    double d5 = xv_dot(ab, cp), d6 = xv_dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) {
        u = 0.0, v = 0.0, w = 1.0;
        goto done;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        w = d2 / (d2 - d6);
        u = 1.0 - w, v = 0.0;
        goto done;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        u = 0.0, v = 1.0 - w;
        goto done;
    }
    {
        double denom = va + vb + vc;
        if (!(denom > 0.0)) {
            /* Degenerate (collapsed) triangle: fall back to the nearest vertex. */
            double da[3], db[3], dc[3];
            xv_sub(da, p, a), xv_sub(db, p, b), xv_sub(dc, p, c);
            double la = xv_dot(da, da), lb = xv_dot(db, db), lc = xv_dot(dc, dc);
            u = (la <= lb && la <= lc), v = (!u && lb <= lc), w = (!u && !v);
            goto done;
        }
        v = vb / denom;
        w = vc / denom;
        u = 1.0 - v - w;
    }
done:
    for (int k = 0; k < 3; ++k) {
        q[k] = p[k] - (u * a[k] + v * b[k] + w * c[k]);
    }
    if (bary) {
        bary[0] = u, bary[1] = v, bary[2] = w;
    }
    return xv_dot(q, q);
}

static double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

double xg_segment_segment_sq(const double *p0, const double *p1, const double *q0, const double *q1, double *s_out,
                             double *t_out)
{
    double d1[3], d2[3], r[3];
    xv_sub(d1, p1, p0);
    xv_sub(d2, q1, q0);
    xv_sub(r, p0, q0);
    double a = xv_dot(d1, d1), e = xv_dot(d2, d2), f = xv_dot(d2, r);
    double s, t;
    const double eps = 1e-30;
    if (a <= eps && e <= eps) {
        s = t = 0.0;
    } else if (a <= eps) {
        s = 0.0;
        t = clamp01(f / e);
    } else {
        double c = xv_dot(d1, r);
        if (e <= eps) {
            t = 0.0;
            s = clamp01(-c / a);
        } else {
            double b = xv_dot(d1, d2);
            double denom = a * e - b * b;
            /* Near-parallel segments: any s works; 0 keeps the result continuous enough. */
            s = denom > 1e-14 * a * e ? clamp01((b * f - c * e) / denom) : 0.0;
            t = (b * s + f) / e;
            if (t < 0.0) {
                t = 0.0;
                s = clamp01(-c / a);
            } else if (t > 1.0) {
                t = 1.0;
                s = clamp01((b - c) / a);
            }
        }
    }
    double cp[3];
    for (int k = 0; k < 3; ++k) {
        cp[k] = (p0[k] + s * d1[k]) - (q0[k] + t * d2[k]);
    }
    if (s_out) {
        *s_out = s;
    }
    if (t_out) {
        *t_out = t;
    }
    return xv_dot(cp, cp);
}

/* Six times the signed volume of (a, b, c, d). */
static double orient3d(const double *a, const double *b, const double *c, const double *d)
{
    double ab[3], ac[3], ad[3], n[3];
    xv_sub(ab, b, a);
    xv_sub(ac, c, a);
    xv_sub(ad, d, a);
    xv_cross(n, ab, ac);
    return xv_dot(n, ad);
}

/* Segment pq strictly crosses triangle abc. A segment lying within 1 micrometre of the
 * triangle's plane is treated as coplanar and not crossing: the sign tests are rounding
 * noise there (float32 inputs), and a real coplanar touch is a zero-distance contact that
 * the CCD sweeps report. */
static bool segment_crosses_triangle(const double *p, const double *q, const double *a, const double *b,
                                     const double *c)
{
    double sp = orient3d(a, b, c, p), sq = orient3d(a, b, c, q);
    if ((sp > 0.0 && sq > 0.0) || (sp < 0.0 && sq < 0.0) || sp == sq) {
        return false;
    }
    double ab[3], ac[3], n[3];
    xv_sub(ab, b, a);
    xv_sub(ac, c, a);
    xv_cross(n, ab, ac);
    double ln = xv_len(n);
    if (!(ln > 0.0) || (fabs(sp) < 1e-6 * ln && fabs(sq) < 1e-6 * ln)) {
        return false;
    }
    double o1 = orient3d(p, q, a, b), o2 = orient3d(p, q, b, c), o3 = orient3d(p, q, c, a);
    return (o1 > 0.0 && o2 > 0.0 && o3 > 0.0) || (o1 < 0.0 && o2 < 0.0 && o3 < 0.0);
}

bool xg_triangles_intersect(const double *a0, const double *a1, const double *a2, const double *b0, const double *b1,
                            const double *b2)
{
    const double *A[3] = {a0, a1, a2}, *B[3] = {b0, b1, b2};
    for (int i = 0; i < 3; ++i) {
        if (segment_crosses_triangle(A[i], A[(i + 1) % 3], b0, b1, b2) ||
            segment_crosses_triangle(B[i], B[(i + 1) % 3], a0, a1, a2)) {
            return true;
        }
    }
    return false;
}

typedef double accd_dist_fn(double x[4][3]);

static double dist_pt(double x[4][3]) { return sqrt(xg_point_triangle_sq(x[0], x[1], x[2], x[3], NULL)); }
static double dist_ee(double x[4][3]) { return sqrt(xg_segment_segment_sq(x[0], x[1], x[2], x[3], NULL, NULL)); }

/* Conservative advancement: the separation can shrink at most lp per unit time, where lp
 * bounds the relative speed of the closest points. Steps aim at eta/2 so each one advances
 * by at least eta/(2 lp) while the separation stays above eta. */
static bool accd(const double *const p[4], const double dp[12], double eta, accd_dist_fn *dist, bool point_tri)
{
    double mean[3] = {0, 0, 0}, d[4][3], x[4][3];
    for (int i = 0; i < 4; ++i) {
        for (int k = 0; k < 3; ++k) {
            mean[k] += 0.25 * dp[3 * i + k];
            x[i][k] = p[i][k];
        }
    }
    double len[4];
    for (int i = 0; i < 4; ++i) {
        for (int k = 0; k < 3; ++k) {
            d[i][k] = dp[3 * i + k] - mean[k];
        }
        len[i] = xv_len(d[i]);
    }
    double lp = point_tri ? len[0] + fmax(len[1], fmax(len[2], len[3])) : fmax(len[0], len[1]) + fmax(len[2], len[3]);
    double dcur = dist(x);
    if (dcur < eta) {
        return true;
    }
    if (!(lp > 0.0)) {
        return false;
    }
    double t = 0.0;
    for (int iter = 0; iter < 20000; ++iter) {
        double step = (dcur - 0.5 * eta) / lp;
        if (t + step >= 1.0) {
            step = 1.0 - t;
        }
        t += step;
        for (int i = 0; i < 4; ++i) {
            for (int k = 0; k < 3; ++k) {
                x[i][k] = p[i][k] + t * dp[3 * i + k];
            }
        }
        dcur = dist(x);
        if (dcur < eta) {
            return true;
        }
        if (t >= 1.0) {
            return false;
        }
    }
    return true; /* undecided after the cap: report conservatively */
}

bool xg_accd_point_triangle(const double *const p[4], const double dp[12], double eta)
{
    return accd(p, dp, eta, dist_pt, true);
}

bool xg_accd_edge_edge(const double *const p[4], const double dp[12], double eta)
{
    return accd(p, dp, eta, dist_ee, false);
}
