/* Constraint gradients against central finite differences, and the geometry kernels
 * against brute-force sampling. */
#include "test.h"
#include "xpbd/xpbd.h"

static void random_point(test_rng *r, double *p, double s)
{
    for (int k = 0; k < 3; ++k) {
        p[k] = test_rng_float(r, -s, s);
    }
}

static void test_membrane_gradients(void)
{
    test_rng r = {0x1234567u};
    int checked = 0;
    for (int trial = 0; trial < 200; ++trial) {
        double rest[3][3], x[3][3], coef[6], area;
        for (int i = 0; i < 3; ++i) {
            random_point(&r, rest[i], 0.05);
        }
        if (!xpbd_membrane_coefficients(rest[0], rest[1], rest[2], coef, &area) || area < 1e-5) {
            continue;
        }
        /* At rest the warp/weft stretch and the shear are zero. */
        double g[9];
        CHECK_NEAR(xpbd_membrane_eval(rest[0], rest[1], rest[2], coef, 0, g), 0.0, 1e-9);
        CHECK_NEAR(xpbd_membrane_eval(rest[0], rest[1], rest[2], coef, 1, g), 0.0, 1e-9);
        CHECK_NEAR(xpbd_membrane_eval(rest[0], rest[1], rest[2], coef, 2, g), 0.0, 1e-9);
        for (int i = 0; i < 3; ++i) {
            for (int k = 0; k < 3; ++k) {
                x[i][k] = rest[i][k] + test_rng_float(&r, -0.02f, 0.02f);
            }
        }
        for (int which = 0; which < 3; ++which) {
            double grad[9];
            xpbd_membrane_eval(x[0], x[1], x[2], coef, which, grad);
            double max_err = 0.0, max_g = 0.0;
            for (int i = 0; i < 3; ++i) {
                for (int k = 0; k < 3; ++k) {
                    const double eps = 1e-7;
                    double save = x[i][k], gg[9];
                    x[i][k] = save + eps;
                    double cp = xpbd_membrane_eval(x[0], x[1], x[2], coef, which, gg);
                    x[i][k] = save - eps;
                    double cm = xpbd_membrane_eval(x[0], x[1], x[2], coef, which, gg);
                    x[i][k] = save;
                    double fd = (cp - cm) / (2 * eps);
                    max_err = fmax(max_err, fabs(fd - grad[3 * i + k]));
                    max_g = fmax(max_g, fabs(grad[3 * i + k]));
                }
            }
            CHECK_MSG(max_err <= 1e-5 * fmax(1.0, max_g), "membrane %d: fd error %g (|g| %g)", which, max_err, max_g);
            checked++;
        }
    }
    CHECK(checked > 300);
}

static void test_dihedral_gradients(void)
{
    test_rng r = {0xabcdefu};
    int checked = 0;
    for (int trial = 0; trial < 300; ++trial) {
        double x[4][3];
        for (int i = 0; i < 4; ++i) {
            random_point(&r, x[i], 0.05);
        }
        double th, grad[12];
        if (!xpbd_dihedral_eval(x[0], x[1], x[2], x[3], &th, grad)) {
            continue;
        }
        /* Skip configurations near the +-pi branch cut, where theta jumps. */
        if (fabs(th) > 3.0) {
            continue;
        }
        double max_err = 0.0, max_g = 0.0, sum[3] = {0, 0, 0};
        for (int i = 0; i < 4; ++i) {
            for (int k = 0; k < 3; ++k) {
                const double eps = 1e-7;
                double save = x[i][k], gg[12], tp, tm;
                x[i][k] = save + eps;
                xpbd_dihedral_eval(x[0], x[1], x[2], x[3], &tp, gg);
                x[i][k] = save - eps;
                xpbd_dihedral_eval(x[0], x[1], x[2], x[3], &tm, gg);
                x[i][k] = save;
                max_err = fmax(max_err, fabs((tp - tm) / (2 * eps) - grad[3 * i + k]));
                max_g = fmax(max_g, fabs(grad[3 * i + k]));
                sum[k] += grad[3 * i + k];
            }
        }
        CHECK_MSG(max_err <= 1e-4 * fmax(1.0, max_g), "dihedral: fd error %g (|g| %g, theta %g)", max_err, max_g, th);
        /* Translation invariance: the gradients sum to zero. */
        CHECK_NEAR(sum[0] + sum[1] + sum[2], 0.0, 1e-6 * fmax(1.0, max_g));
        checked++;
    }
    CHECK(checked > 200);
}

static void test_dihedral_flat_and_sign(void)
{
    /* Flat hinge: theta = 0 with a well-defined gradient (the unsigned acos form has none). */
    double x0[3] = {0, 0, 0}, x1[3] = {1, 0, 0}, x2[3] = {0.5, 0, 1}, x3[3] = {0.5, 0, -1};
    double th, grad[12];
    CHECK(xpbd_dihedral_eval(x0, x1, x2, x3, &th, grad));
    CHECK_NEAR(th, 0.0, 1e-12);
    CHECK(fabs(grad[7]) > 0.1); /* wing 2 moves along the normal (y) */
    /* Folding the wings either way gives angles of opposite sign. */
    double up[3] = {0.5, 0.5, -1}, down[3] = {0.5, -0.5, -1}, ta, tb;
    xpbd_dihedral_eval(x0, x1, x2, up, &ta, grad);
    xpbd_dihedral_eval(x0, x1, x2, down, &tb, grad);
    CHECK(ta * tb < 0.0);
    CHECK_NEAR(ta, -tb, 1e-12);
    CHECK_NEAR(fabs(ta), atan(0.5), 1e-12);
}

static void test_point_triangle_distance(void)
{
    test_rng r = {99};
    for (int trial = 0; trial < 100; ++trial) {
        double a[3], b[3], c[3], p[3], bary[3];
        random_point(&r, a, 1), random_point(&r, b, 1), random_point(&r, c, 1), random_point(&r, p, 1.5);
        double d2 = geo_point_triangle_sq(p, a, b, c, bary);
        /* Brute force over a barycentric lattice never beats the exact minimum. */
        double best = 1e30;
        const int N = 60;
        for (int i = 0; i <= N; ++i) {
            for (int j = 0; i + j <= N; ++j) {
                double u = (double)i / N, v = (double)j / N, w = 1 - u - v, q[3];
                for (int k = 0; k < 3; ++k) {
                    q[k] = u * a[k] + v * b[k] + w * c[k] - p[k];
                }
                best = fmin(best, geo_dot(q, q));
            }
        }
        CHECK(d2 <= best + 1e-12);
        CHECK(sqrt(best) - sqrt(d2) < 0.05);
        CHECK_NEAR(bary[0] + bary[1] + bary[2], 1.0, 1e-12);
        CHECK(bary[0] >= -1e-12 && bary[1] >= -1e-12 && bary[2] >= -1e-12);
    }
}

static void test_segment_distance(void)
{
    test_rng r = {77};
    for (int trial = 0; trial < 100; ++trial) {
        double p0[3], p1[3], q0[3], q1[3], s, t;
        random_point(&r, p0, 1), random_point(&r, p1, 1), random_point(&r, q0, 1), random_point(&r, q1, 1);
        double d2 = geo_segment_segment_sq(p0, p1, q0, q1, &s, &t);
        double best = 1e30;
        for (int i = 0; i <= 200; ++i) {
            for (int j = 0; j <= 200; ++j) {
                double a = i / 200.0, b = j / 200.0, d[3];
                for (int k = 0; k < 3; ++k) {
                    d[k] = (p0[k] + a * (p1[k] - p0[k])) - (q0[k] + b * (q1[k] - q0[k]));
                }
                best = fmin(best, geo_dot(d, d));
            }
        }
        CHECK(d2 <= best + 1e-12);
        CHECK(sqrt(best) - sqrt(d2) < 0.02);
        CHECK(s >= 0 && s <= 1 && t >= 0 && t <= 1);
    }
}

TEST_MAIN(TEST_CASE(test_membrane_gradients), TEST_CASE(test_dihedral_gradients), TEST_CASE(test_dihedral_flat_and_sign),
          TEST_CASE(test_point_triangle_distance), TEST_CASE(test_segment_distance))
