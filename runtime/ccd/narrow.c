/* Narrow-phase CCD for vertex–face and edge–edge pairs on linear trajectories, t in [0, 1].
 *
 * 1. The coplanarity cubic f(t) = det(u(t), v(t), w(t)) is built in double precision in coordinates
 *    translated to the first point, with an a-priori bound e_f on |computed f - exact f| over [0, 1].
 * 2. Yuksel's decomposition: the critical points (roots of f') split [0, 1] into monotone pieces. On
 *    each piece the set {t : |f(t)| <= e_f} is one interval ("band") whose ends are found with a
 *    safeguarded Newton iteration on f -/+ e_f, keeping the bracket end on the outer side. Any
 *    contact time is a root of the exact f, so it lies inside a band.
 * 3. Inside each band, earliest first, conservative advancement on the exact point–triangle or
 *    segment–segment distance D(t): D cannot fall faster than the largest relative vertex speed L,
 *    so stepping by (D - err) / L never passes a contact. The band reports a hit as soon as the lower
 *    bound D - err is <= eta. A generic crossing needs one distance evaluation; degenerate classes
 *    (coplanar for all t, parallel edges, zero motion, touching at t = 0 or 1, end-point contact) all
 *    reduce to the same distance test and need no special root finding.
 * docs/CCD.md has the argument and the measured false-positive rates. */
#include "ccd/ccd_internal.h"

#include <float.h>
#include <math.h>

#define ADVANCE_CAP 256 /* distance evaluations per band before a conservative hit */

static inline double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static inline void cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static inline void sub3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[0] - b[0];
    out[1] = a[1] - b[1];
    out[2] = a[2] - b[2];
}

/* Plain comparisons: libm's fmin/fmax are out-of-line calls because of their NaN rules, and every
 * value reaching them here is finite (inputs are checked first). */
static inline double dmax(double a, double b) { return a > b ? a : b; }
static inline double dmin(double a, double b) { return a < b ? a : b; }

static inline double maxabs3(const double a[3]) { return dmax(fabs(a[0]), dmax(fabs(a[1]), fabs(a[2]))); }

static inline double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

/* Distance from p to the closed segment ab. */
static double point_segment(const double p[3], const double a[3], const double b[3])
{
    double ab[3], ap[3];
    sub3(b, a, ab);
    sub3(p, a, ap);
    double l2 = dot3(ab, ab);
    double s = l2 > 0.0 ? clamp01(dot3(ap, ab) / l2) : 0.0;
    double d[3] = {ap[0] - s * ab[0], ap[1] - s * ab[1], ap[2] - s * ab[2]};
    return sqrt(dot3(d, d));
}

/* Distance from p to the closed triangle abc. *slack receives how much the result may exceed the
 * true distance beyond rounding: for slivers the interior is not used and the edges are within the
 * triangle's smallest height of every interior point. */
static double point_triangle(const double p[3], const double a[3], const double b[3], const double c[3],
                             double *slack)
{
    double d = dmin(point_segment(p, a, b), dmin(point_segment(p, b, c), point_segment(p, c, a)));
    double e0[3], e1[3], n[3];
    sub3(b, a, e0);
    sub3(c, a, e1);
    cross3(e0, e1, n);
    double nn = dot3(n, n);
    double l0 = dot3(e0, e0), l1 = dot3(e1, e1);
    *slack = 0.0;
    if (nn > 1e-12 * l0 * l1) {
        double w[3], x[3];
        sub3(p, a, w);
        cross3(e0, w, x);
        double s1 = dot3(x, n);
        cross3(w, e1, x);
        double s2 = dot3(x, n);
        if (s1 >= 0.0 && s2 >= 0.0 && s1 + s2 <= nn) {
            d = dmin(d, fabs(dot3(w, n)) / sqrt(nn));
        }
    } else {
        double bc[3];
        sub3(c, b, bc);
        double longest = sqrt(dmax(dot3(bc, bc), dmax(l0, l1)));
        *slack = longest > 0.0 ? sqrt(nn) / longest : 0.0;
    }
    return d;
}

/* Distance between closed segments a0a1 and b0b1: the clamped closest-point solution, checked
 * against the four end-point distances (which fix the ill-conditioned near-parallel case). */
static double segment_segment(const double a0[3], const double a1[3], const double b0[3], const double b1[3])
{
    double d1[3], d2[3], r[3];
    sub3(a1, a0, d1);
    sub3(b1, b0, d2);
    sub3(a0, b0, r);
    double a = dot3(d1, d1), e = dot3(d2, d2), f = dot3(d2, r);
    double s = 0.0, u = 0.0;
    if (a > 0.0 && e > 0.0) {
        double c = dot3(d1, r), b = dot3(d1, d2);
        double denom = a * e - b * b;
        s = denom > 0.0 ? clamp01((b * f - c * e) / denom) : 0.0;
        u = (b * s + f) / e;
        if (u < 0.0) {
            u = 0.0;
            s = clamp01(-c / a);
        } else if (u > 1.0) {
            u = 1.0;
            s = clamp01((b - c) / a);
        }
    } else if (a > 0.0) {
        s = clamp01(-dot3(d1, r) / a);
    } else if (e > 0.0) {
        u = clamp01(f / e);
    }
    double w[3] = {r[0] + s * d1[0] - u * d2[0], r[1] + s * d1[1] - u * d2[1], r[2] + s * d1[2] - u * d2[2]};
    double d = sqrt(dot3(w, w));
    d = dmin(d, dmin(point_segment(a0, b0, b1), point_segment(a1, b0, b1)));
    d = dmin(d, dmin(point_segment(b0, a0, a1), point_segment(b1, a0, a1)));
    return d;
}

/* ---- cubic ------------------------------------------------------------------------------ */

typedef struct cubic {
    double c[4]; /* increasing degree */
} cubic;

static inline double cubic_eval(const cubic *q, double t) { return ((q->c[3] * t + q->c[2]) * t + q->c[1]) * t + q->c[0]; }

static inline double cubic_deriv(const cubic *q, double t) { return (3.0 * q->c[3] * t + 2.0 * q->c[2]) * t + q->c[1]; }

/* On [l, r] the function g = f - shift is monotone and changes sign (g(l) and g(r) have the signs
 * given by neg_left). Returns a point on the requested side of the root: want_left gives x with
 * x <= root (g(x) has the sign of g(l)), otherwise x >= root. Safeguarded Newton (Yuksel): Newton
 * steps inside the bracket, bisection otherwise; after convergence a probe one tolerance outward
 * confirms the side, as in Yuksel's error-bounded variant. Any bracket end is a valid answer, so
 * the iteration cap only costs precision, never correctness. */
static double band_edge(const cubic *q, double shift, double l, double r, bool neg_left, bool want_left)
{
    /* Any point on the right side is valid; the tolerance only trades band width for iterations. */
    const double tol = 1e-10 * (r - l) + 1e-15;
    double bl = l, br = r;
    double gl = cubic_eval(q, l) - shift, gr = cubic_eval(q, r) - shift;
    double x = gr != gl ? l + (r - l) * (gl / (gl - gr)) : 0.5 * (l + r); /* secant start */
    if (!(x > l && x < r)) {
        x = 0.5 * (l + r);
    }
    for (int it = 0; it < 48 && br - bl > tol; ++it) {
        double g = cubic_eval(q, x) - shift;
        bool left_side = neg_left ? g < 0.0 : g > 0.0;
        if (left_side) {
            bl = x;
        } else {
            br = x;
        }
        double dg = cubic_deriv(q, x);
        double xn = dg != 0.0 ? x - g / dg : x;
        if (xn > bl && xn < br) {
            if (fabs(xn - x) <= tol) {
                /* Converged: probe just outside on the wanted side. */
                double probe = want_left ? dmax(bl, xn - 4.0 * tol) : dmin(br, xn + 4.0 * tol);
                double gp = cubic_eval(q, probe) - shift;
                bool probe_left = neg_left ? gp < 0.0 : gp > 0.0;
                if (probe_left == want_left) {
                    return probe;
                }
                x = probe;
                continue;
            }
            x = xn;
        } else {
            x = 0.5 * (bl + br);
        }
    }
    return want_left ? bl : br;
}

/* ---- the query -------------------------------------------------------------------------- */

typedef struct query {
    double x0[4][3]; /* translated positions at t = 0 */
    double d[4][3];  /* displacements */
    bool vf;
} query;

static double query_distance(const query *Q, double t, double *slack)
{
    double p[4][3];
    for (int i = 0; i < 4; ++i) {
        for (int k = 0; k < 3; ++k) {
            p[i][k] = Q->x0[i][k] + t * Q->d[i][k];
        }
    }
    if (Q->vf) {
        return point_triangle(p[0], p[1], p[2], p[3], slack);
    }
    *slack = 0.0;
    return segment_segment(p[0], p[1], p[2], p[3]);
}

/* Largest relative speed between a point of one primitive and a point of the other: a bound on
 * |dD/dt| because D is invariant to common translation and the closest points are convex
 * combinations of the vertices. */
static double relative_speed(const query *Q)
{
    double L2 = 0.0;
    int first_b = Q->vf ? 1 : 2;
    for (int i = 0; i < first_b; ++i) {
        for (int j = first_b; j < 4; ++j) {
            double v[3];
            sub3(Q->d[i], Q->d[j], v);
            L2 = dmax(L2, dot3(v, v));
        }
    }
    return sqrt(L2) * (1.0 + 1e-12);
}

/* Conservative advancement from the band start ta to the end r of its monotone piece. The band's
 * far end is not computed: once f is beyond 2 tau on the exit side (positive for an increasing
 * piece) it stays there for the rest of the piece, so no contact remains. */
static bool advance_band(const query *Q, const cubic *q, double ta, double r, bool increasing, double tau, double eta,
                         double err, double L, double *toi, ccd_narrow_stats *stats)
{
    double t = ta;
    for (int it = 0; it < ADVANCE_CAP; ++it) {
        double slack;
        double D = query_distance(Q, t, &slack);
        if (stats) {
            stats->distance_evals++;
        }
        double lower = D - err - slack;
        if (!(lower > eta)) {
            *toi = t;
            return true;
        }
        if (L <= 0.0) {
            return false; /* no relative motion: the distance is constant */
        }
        t += lower / L;
        if (t > r) {
            return false;
        }
        double y = cubic_eval(q, t);
        if (increasing ? y > 2.0 * tau : y < -2.0 * tau) {
            return false;
        }
    }
    if (stats) {
        stats->capped++;
    }
    *toi = t;
    return true;
}

static bool ccd_query(const double P[24], double eta, bool vf, double *toi, ccd_narrow_stats *stats)
{
    if (stats) {
        stats->queries++;
    }
    double S = 0.0;
    for (int i = 0; i < 24; ++i) {
        if (!isfinite(P[i])) {
            *toi = 0.0;
            return true;
        }
        S = dmax(S, fabs(P[i]));
    }
    query Q;
    Q.vf = vf;
    double M = 0.0;
    for (int i = 0; i < 4; ++i) {
        for (int k = 0; k < 3; ++k) {
            Q.x0[i][k] = P[3 * i + k] - P[k];
            double x1 = P[12 + 3 * i + k] - P[k];
            Q.d[i][k] = P[12 + 3 * i + k] - P[3 * i + k];
            M = dmax(M, dmax(fabs(Q.x0[i][k]), fabs(x1)));
        }
    }
    /* Distance evaluation error: rounding of the translated coordinates (S) and of the clamped
     * closest-point parameters for near-parallel edges (at most ~sqrt(eps) times the extent M). */
    double err = 1e-7 * M + 1e-13 * S;
    if (!(eta > 2.0 * err)) {
        eta = 2.0 * err;
    }

    /* Vectors spanning the tetrahedron: VF u = b - a, v = c - a, w = p - a; EE u = a1 - a0,
     * v = b0 - a0, w = b1 - a0. */
    int iu0, iu1, iv0, iv1, iw0, iw1;
    if (vf) {
        iu0 = 2, iu1 = 1, iv0 = 3, iv1 = 1, iw0 = 0, iw1 = 1;
    } else {
        iu0 = 1, iu1 = 0, iv0 = 2, iv1 = 0, iw0 = 3, iw1 = 0;
    }
    double u0[3], v0[3], w0[3], du[3], dv[3], dw[3];
    sub3(Q.x0[iu0], Q.x0[iu1], u0);
    sub3(Q.x0[iv0], Q.x0[iv1], v0);
    sub3(Q.x0[iw0], Q.x0[iw1], w0);
    sub3(Q.d[iu0], Q.d[iu1], du);
    sub3(Q.d[iv0], Q.d[iv1], dv);
    sub3(Q.d[iw0], Q.d[iw1], dw);
    double vw[3], x1[3], x2[3], dvdw[3];
    cross3(v0, w0, vw);
    cross3(dv, w0, x1);
    cross3(v0, dw, x2);
    cross3(dv, dw, dvdw);
    double mix[3] = {x1[0] + x2[0], x1[1] + x2[1], x1[2] + x2[2]};
    cubic q;
    q.c[0] = dot3(u0, vw);
    q.c[1] = dot3(du, vw) + dot3(u0, mix);
    q.c[2] = dot3(u0, dvdw) + dot3(du, mix);
    q.c[3] = dot3(du, dvdw);
    /* Every coefficient is a sum of det terms of (u0 or du, v0 or dv, w0 or dw); the absolute sum of
     * all their products is at most 6 (|u0|+|du|)(|v0|+|dv|)(|w0|+|dw|) in max norms. The constant
     * covers coefficient and Horner rounding (about 30 eps) with a wide margin. */
    double perm = 6.0 * (maxabs3(u0) + maxabs3(du)) * (maxabs3(v0) + maxabs3(dv)) * (maxabs3(w0) + maxabs3(dw));
    double tau = 1e-13 * perm;

    /* Yuksel: critical points of f in (0, 1) split it into monotone pieces. */
    double brk[4];
    int nb = 0;
    brk[nb++] = 0.0;
    double a3 = 3.0 * q.c[3], b2 = q.c[2], c1 = q.c[1];
    double delta = b2 * b2 - a3 * c1;
    if (delta > 0.0) {
        double sd = sqrt(delta);
        double qq = -(b2 + copysign(sd, b2));
        double r1 = a3 != 0.0 ? qq / a3 : INFINITY;
        double r2 = qq != 0.0 ? c1 / qq : INFINITY;
        if (r1 > r2) {
            double tmp = r1;
            r1 = r2;
            r2 = tmp;
        }
        if (r1 > 0.0 && r1 < 1.0) {
            brk[nb++] = r1;
        }
        if (r2 > 0.0 && r2 < 1.0 && r2 != r1) {
            brk[nb++] = r2;
        }
    }
    brk[nb++] = 1.0;

    double L = -1.0;
    double y[4];
    for (int i = 0; i < nb; ++i) {
        y[i] = cubic_eval(&q, brk[i]);
    }
    for (int i = 0; i + 1 < nb; ++i) {
        double l = brk[i], r = brk[i + 1], yl = y[i], yr = y[i + 1];
        /* Inside a piece the computed critical points are off by rounding only, so f stays within
         * a second-order amount of its end values; the 2 tau test absorbs that. */
        if (dmin(yl, yr) > 2.0 * tau || dmax(yl, yr) < -2.0 * tau) {
            continue;
        }
        bool increasing = yr >= yl;
        double ta;
        if (increasing) {
            ta = yl >= -tau ? l : band_edge(&q, -tau, l, r, true, true);
        } else {
            ta = yl <= tau ? l : band_edge(&q, tau, l, r, false, true);
        }
        if (stats) {
            stats->bands++;
        }
        if (L < 0.0) {
            L = relative_speed(&Q);
            /* D(t) >= D(0) - L t: pairs that cannot close their gap in one step are done with one
             * distance evaluation instead of a band search. */
            double slack;
            double D0 = query_distance(&Q, 0.0, &slack);
            if (stats) {
                stats->distance_evals++;
            }
            if (D0 - err - slack - L > eta) {
                return false;
            }
        }
        if (advance_band(&Q, &q, ta, r, increasing, tau, eta, err, L, toi, stats)) {
            return true;
        }
    }
    return false;
}

bool ccd_vf(const double points[24], double eta, double *toi, ccd_narrow_stats *stats)
{
    return ccd_query(points, eta, true, toi, stats);
}

bool ccd_ee(const double points[24], double eta, double *toi, ccd_narrow_stats *stats)
{
    return ccd_query(points, eta, false, toi, stats);
}

int weft_ccd_vertex_face(const double points[24], double min_separation, double *toi)
{
    double t = 1.0;
    if (!points) {
        return 0;
    }
    double eta = min_separation > 0.0 ? min_separation : WEFT_CCD_DEFAULT_MIN_SEPARATION;
    bool hit = ccd_vf(points, eta, &t, NULL);
    if (toi) {
        *toi = hit ? t : 1.0;
    }
    return hit ? 1 : 0;
}

int weft_ccd_edge_edge(const double points[24], double min_separation, double *toi)
{
    double t = 1.0;
    if (!points) {
        return 0;
    }
    double eta = min_separation > 0.0 ? min_separation : WEFT_CCD_DEFAULT_MIN_SEPARATION;
    bool hit = ccd_ee(points, eta, &t, NULL);
    if (toi) {
        *toi = hit ? t : 1.0;
    }
    return hit ? 1 : 0;
}
