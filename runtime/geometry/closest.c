/* Distance, intersection and conservative-advancement kernels in double precision. */
#include "geometry/geometry.h"

#include <math.h>

double geo_point_triangle_sq(const double *p, const double *a, const double *b, const double *c, double bary[3])
{
    /* Voronoi-region walk over the triangle's vertices, edges and face. */
    double ab[3], ac[3], ap[3], bp[3], cp[3], q[3];
    geo_sub(ab, b, a);
    geo_sub(ac, c, a);
    geo_sub(ap, p, a);
    double d1 = geo_dot(ab, ap), d2 = geo_dot(ac, ap);
    double u, v, w;
    if (d1 <= 0.0 && d2 <= 0.0) {
        u = 1.0, v = 0.0, w = 0.0;
        goto done;
    }
    geo_sub(bp, p, b);
    double d3 = geo_dot(ab, bp), d4 = geo_dot(ac, bp);
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
    geo_sub(cp, p, c);
    double d5 = geo_dot(ab, cp), d6 = geo_dot(ac, cp);
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
            geo_sub(da, p, a), geo_sub(db, p, b), geo_sub(dc, p, c);
            double la = geo_dot(da, da), lb = geo_dot(db, db), lc = geo_dot(dc, dc);
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
    return geo_dot(q, q);
}

static double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

double geo_segment_segment_sq(const double *p0, const double *p1, const double *q0, const double *q1, double *s_out,
                             double *t_out)
{
    double d1[3], d2[3], r[3];
    geo_sub(d1, p1, p0);
    geo_sub(d2, q1, q0);
    geo_sub(r, p0, q0);
    double a = geo_dot(d1, d1), e = geo_dot(d2, d2), f = geo_dot(d2, r);
    double s, t;
    const double eps = 1e-30;
    if (a <= eps && e <= eps) {
        s = t = 0.0;
    } else if (a <= eps) {
        s = 0.0;
        t = clamp01(f / e);
    } else {
        double c = geo_dot(d1, r);
        if (e <= eps) {
            t = 0.0;
            s = clamp01(-c / a);
        } else {
            double b = geo_dot(d1, d2);
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
    return geo_dot(cp, cp);
}
