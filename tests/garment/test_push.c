/* Collider push (weft_garment_def.collision.push, runtime/garment/near.c): points placed inside
 * and just outside a box end where the box's exact distance field says (nearest face, edge or
 * corner plus the thickness); deeper ones, pinned ones and ones that came through from beyond
 * stay; beyond a thin wedge's sharp edge, where the two faces' normals disagree, both sides are
 * told outside; bad settings fail at creation and leave no garment.
 *
 * The step is LBS on a still collider, which returns the initial positions, so the push is the
 * only thing that moves a vertex.
 *
 * The clearance: on a sphere that turns, travels and breathes, with cloth points wandering around
 * it for 240 frames (inside, deep inside, near, and beyond the search's radius), the push that
 * skips the vertices its motion bound keeps clear gives the same positions, bit for bit, as the
 * push that searches every vertex every step, while searching fewer than half of them. */
#include "../xpbd/scene.h"
#include "garment/garment.h"
#include "test.h"

#include <math.h>
#include <string.h>

#define THICK 0.01f
#define DEPTH 0.02f

static const float k_lo[3] = {-0.1f, 0.0f, -0.1f}, k_hi[3] = {0.1f, 0.2f, 0.1f};

/* An LBS garment of the sheet's topology around collider col, started at `points`, pushing at
 * `push` (CCD off: the push itself is under test). */
static weft_garment_def push_def(const test_mesh *sheet, const test_mesh *col, const float *points, float push)
{
    weft_garment_def gd = weft_default_garment_def();
    gd.method = WEFT_METHOD_LBS;
    gd.ccd.enabled = false;
    gd.rest_positions = sheet->pos;
    gd.vertex_count = sheet->nv;
    gd.triangles = sheet->tris;
    gd.triangle_count = sheet->nt;
    gd.initial_positions = points;
    gd.collider_rest_positions = col->pos;
    gd.collider_vertex_count = col->nv;
    gd.collider_triangles = col->tris;
    gd.collider_triangle_count = col->nt;
    gd.collision.push = push;
    gd.collision.push_depth = DEPTH;
    return gd;
}

static weft_garment *make(weft_context *ctx, const test_mesh *sheet, const test_mesh *col, const float *points,
                          float push, weft_result expect)
{
    const weft_garment_def gd = push_def(sheet, col, points, push);
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), expect);
    return g;
}

/* Where the exact distance field of the box puts p: unchanged when deeper than DEPTH or farther
 * than THICK, else THICK in front of the nearest surface point. */
static void box_oracle(const float p[3], float out[3])
{
    float q[3], d2 = 0.0f;
    bool inside = true;
    for (int k = 0; k < 3; ++k) {
        q[k] = fminf(fmaxf(p[k], k_lo[k]), k_hi[k]);
        d2 += (p[k] - q[k]) * (p[k] - q[k]);
        inside = inside && p[k] > k_lo[k] && p[k] < k_hi[k];
    }
    memcpy(out, p, 3 * sizeof(float));
    if (inside) { /* nearest face */
        int axis = 0, hi = 0;
        float best = INFINITY;
        for (int k = 0; k < 3; ++k) {
            if (p[k] - k_lo[k] < best) {
                best = p[k] - k_lo[k], axis = k, hi = 0;
            }
            if (k_hi[k] - p[k] < best) {
                best = k_hi[k] - p[k], axis = k, hi = 1;
            }
        }
        if (best <= DEPTH) {
            out[axis] = hi ? k_hi[axis] + THICK : k_lo[axis] - THICK;
        }
        return;
    }
    const float d = sqrtf(d2);
    if (d < THICK) {
        for (int k = 0; k < 3; ++k) {
            out[k] = q[k] + THICK * (p[k] - q[k]) / d;
        }
    }
}

static void test_push_matches_the_box_distance_field(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh sheet = test_sheet(3, 3, 0.5f, 0.5f, 0.0f, 0.5f, 0.0f), box = test_box(k_lo, k_hi);
    const float s3 = 0.003f;
    const float pts[9][3] = {
        {0.02f, 0.195f, 0.03f},   /* inside, 5 mm under the top */
        {0.085f, 0.1f, 0.0f},     /* inside, 15 mm from the +x side */
        {0.0f, 0.1f, 0.0f},       /* inside, 10 cm deep: left */
        {0.104f, 0.203f, 0.0f},   /* outside, 5 mm off the top +x edge */
        {0.1f + s3, 0.2f + s3, 0.1f + s3}, /* outside, 5.2 mm off a corner */
        {0.05f, -0.004f, 0.05f},  /* under the bottom, 4 mm */
        {0.5f, 0.5f, 0.5f},       /* far away */
        {-0.02f, 0.195f, 0.0f},   /* inside, pinned */
        {0.0f, 0.19f, 0.0f},      /* inside, but came up from 15 cm: from beyond the top */
    };
    weft_garment *plain = make(ctx, &sheet, &box, &pts[0][0], 0.0f, WEFT_OK);
    weft_garment *g = make(ctx, &sheet, &box, &pts[0][0], THICK, WEFT_OK);
    float before[9][3];
    memcpy(before, pts, sizeof before);
    before[8][1] = 0.04f; /* vertex 8 at t: 15 cm lower, the far side of the surface point it ends near */
    CHECK_RESULT(weft_garment_set_state(g, &before[0][0], &before[0][0]), WEFT_OK);
    const uint32_t pin = 7;
    weft_garment *both[2] = {plain, g};
    for (int k = 0; k < 2; ++k) {
        CHECK_RESULT(weft_garment_set_collider(both[k], box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_set_pins(both[k], &pin, pts[7], 1), WEFT_OK);
        CHECK_RESULT(weft_garment_step(both[k]), WEFT_OK);
    }
    /* The control: LBS on a still collider returns the start, so what moves below is the push. */
    const float *x0 = weft_garment_positions(plain), *x = weft_garment_positions(g);
    for (int v = 0; v < 9; ++v) {
        for (int k = 0; k < 3; ++k) {
            CHECK_MSG(fabsf(x0[3 * v + k] - pts[v][k]) < 1e-6f, "LBS moved vertex %d on a still collider", v);
        }
    }
    for (int v = 0; v < 9; ++v) {
        float want[3];
        if (v == 7 || v == 8) {
            memcpy(want, pts[v], sizeof want);
        } else {
            box_oracle(pts[v], want);
        }
        for (int k = 0; k < 3; ++k) {
            CHECK_MSG(fabsf(x[3 * v + k] - want[k]) < 2e-6f, "vertex %d axis %d: %.7f, want %.7f", v, k,
                      (double)x[3 * v + k], (double)want[k]);
        }
    }
    const weft_step_stats st = weft_garment_stats(g);
    CHECK_EQ_INT((int)st.pushed_vertices, 5);
    CHECK_EQ_INT((int)st.push_from_far_side, 1); /* the one from beyond; the deep one is not looked at */
    CHECK_EQ_INT((int)weft_garment_stats(plain).pushed_vertices, 0);
    weft_garment_destroy(plain);
    weft_garment_destroy(g);
    test_mesh_free(&box);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

/* A closed triangular prism with a 10-degree edge at x = 0.1 (along z), wound outward. */
static test_mesh wedge(void)
{
    test_mesh m = {0};
    m.nv = 6;
    m.nt = 8;
    m.pos = malloc(sizeof(float) * 18);
    m.tris = malloc(sizeof(uint32_t) * 24);
    const float h = 0.2f * tanf(5.0f * 3.14159265f / 180.0f); /* half the base for a 10-degree tip */
    const float cs[3][2] = {{0.1f, 0.1f}, {-0.1f, 0.1f - h}, {-0.1f, 0.1f + h}}; /* tip, base low, base high */
    for (int z = 0; z < 2; ++z) {
        for (int i = 0; i < 3; ++i) {
            float *p = m.pos + 3 * (3 * z + i);
            p[0] = cs[i][0], p[1] = cs[i][1], p[2] = z ? 0.1f : -0.1f;
        }
    }
    static const uint32_t t[24] = {0, 1, 2, 3, 4, 5, 0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4, 2, 0, 3, 2, 3, 5};
    memcpy(m.tris, t, sizeof t);
    const float c[3] = {(0.1f - 0.2f) / 3.0f, 0.1f, 0.0f}; /* centroid: flip triangles facing it */
    for (uint32_t k = 0; k < m.nt; ++k) {
        uint32_t *tri = m.tris + 3 * k;
        const float *a = m.pos + 3 * tri[0], *b = m.pos + 3 * tri[1], *d = m.pos + 3 * tri[2];
        const float u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
        const float n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        if (n[0] * (a[0] - c[0]) + n[1] * (a[1] - c[1]) + n[2] * (a[2] - c[2]) < 0.0f) {
            const uint32_t s = tri[1];
            tri[1] = tri[2], tri[2] = s;
        }
    }
    return m;
}

/* Beyond the sharp edge the nearest point is on the edge, and a direction near one face's
 * normal is 160 degrees from the other's: a face normal alone would call one of these points
 * inside and push it into the wedge. The pseudonormal calls both outside. */
static void test_push_sign_at_a_sharp_edge(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh sheet = test_sheet(3, 3, 0.5f, 0.5f, 0.0f, 0.5f, 0.0f), col = wedge();
    const float a = 5.0f * 3.14159265f / 180.0f;
    const float up[2] = {sinf(a), cosf(a)}, down[2] = {sinf(a), -cosf(a)}; /* the faces' normals (x, y) */
    float pts[9][3];
    for (int v = 0; v < 9; ++v) { /* far away by default */
        pts[v][0] = 1.0f + 0.1f * (float)v, pts[v][1] = 1.0f, pts[v][2] = 0.0f;
    }
    float dirs[2][2];
    for (int s = 0; s < 2; ++s) { /* 90 % one face normal, 10 % the other: in the edge's region */
        const float *n1 = s ? down : up, *n2 = s ? up : down;
        const float dx = 0.9f * n1[0] + 0.1f * n2[0], dy = 0.9f * n1[1] + 0.1f * n2[1];
        const float len = sqrtf(dx * dx + dy * dy);
        dirs[s][0] = dx / len, dirs[s][1] = dy / len;
        pts[s][0] = 0.1f + 0.004f * dirs[s][0];
        pts[s][1] = 0.1f + 0.004f * dirs[s][1];
        pts[s][2] = 0.03f * (float)(s ? 1 : -1);
    }
    weft_garment *g = make(ctx, &sheet, &col, &pts[0][0], THICK, WEFT_OK);
    CHECK_RESULT(weft_garment_set_collider(g, col.pos), WEFT_OK);
    CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    const float *x = weft_garment_positions(g);
    for (int s = 0; s < 2; ++s) {
        const float want[3] = {0.1f + THICK * dirs[s][0], 0.1f + THICK * dirs[s][1], pts[s][2]};
        for (int k = 0; k < 3; ++k) {
            CHECK_MSG(fabsf(x[3 * s + k] - want[k]) < 2e-6f, "side %d axis %d: %.7f, want %.7f", s, k,
                      (double)x[3 * s + k], (double)want[k]);
        }
    }
    CHECK_EQ_INT((int)weft_garment_stats(g).pushed_vertices, 2);
    CHECK_EQ_INT((int)weft_garment_stats(g).push_from_far_side, 0);
    weft_garment_destroy(g);
    test_mesh_free(&col);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

/* With CCD: a vertex the last step left inside the box leaves it. CCD alone would stop it on its
 * way out as a crossing; the push with CCD lets it out (stats.ccd_let_out) and it ends where the
 * distance field says. */
static void test_push_with_ccd_lets_cloth_out(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh sheet = test_sheet(3, 3, 0.5f, 0.5f, 0.0f, 0.5f, 0.0f), box = test_box(k_lo, k_hi);
    float pts[9][3];
    for (int v = 0; v < 9; ++v) { /* a grid far above the box, its middle vertex in the box */
        pts[v][0] = -0.3f + 0.3f * (float)(v % 3), pts[v][1] = 0.6f, pts[v][2] = -0.3f + 0.3f * (float)(v / 3);
    }
    const float in[3] = {0.02f, 0.195f, 0.03f}; /* 5 mm under the top */
    memcpy(pts[4], in, sizeof in);
    weft_garment_def gd = push_def(&sheet, &box, &pts[0][0], THICK);
    gd.ccd.enabled = true;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    CHECK_RESULT(weft_garment_set_collider(g, box.pos), WEFT_OK);
    CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    const float *x = weft_garment_positions(g);
    float want[3];
    box_oracle(in, want);
    for (int k = 0; k < 3; ++k) {
        CHECK_MSG(fabsf(x[3 * 4 + k] - want[k]) < 2e-6f, "axis %d: %.7f, want %.7f", k, (double)x[3 * 4 + k],
                  (double)want[k]);
    }
    const weft_step_stats st = weft_garment_stats(g);
    CHECK_EQ_INT((int)st.ccd_let_out, 1);
    CHECK_EQ_INT((int)st.pushed_vertices, 1);
    weft_garment_destroy(g);
    test_mesh_free(&box);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

/* A UV sphere of radius 1 at the origin, wound outward: its unit directions. */
static test_mesh unit_sphere(uint32_t slices, uint32_t stacks)
{
    test_mesh m = {0};
    m.nv = slices * (stacks - 1) + 2;
    m.nt = 2 * slices * (stacks - 1);
    m.pos = malloc(sizeof(float) * 3 * m.nv);
    m.tris = malloc(sizeof(uint32_t) * 3 * m.nt);
    const double pi = 3.14159265358979323846;
    m.pos[0] = 0.0f, m.pos[1] = 1.0f, m.pos[2] = 0.0f;
    for (uint32_t j = 1; j < stacks; ++j) {
        for (uint32_t i = 0; i < slices; ++i) {
            const double th = pi * j / stacks, ph = 2.0 * pi * i / slices;
            float *p = m.pos + 3 * (1 + (j - 1) * slices + i);
            p[0] = (float)(sin(th) * cos(ph)), p[1] = (float)cos(th), p[2] = (float)(sin(th) * sin(ph));
        }
    }
    const uint32_t south = m.nv - 1;
    m.pos[3 * south] = 0.0f, m.pos[3 * south + 1] = -1.0f, m.pos[3 * south + 2] = 0.0f;
    uint32_t *t = m.tris;
    for (uint32_t i = 0; i < slices; ++i) {
        const uint32_t a = 1 + i, b = 1 + (i + 1) % slices;
        t[0] = 0, t[1] = b, t[2] = a, t += 3;
        const uint32_t c = 1 + (stacks - 2) * slices + i, d = 1 + (stacks - 2) * slices + (i + 1) % slices;
        t[0] = south, t[1] = c, t[2] = d, t += 3;
    }
    for (uint32_t j = 1; j + 1 < stacks; ++j) {
        for (uint32_t i = 0; i < slices; ++i) {
            const uint32_t a = 1 + (j - 1) * slices + i, b = 1 + (j - 1) * slices + (i + 1) % slices;
            const uint32_t c = a + slices, d = b + slices;
            t[0] = a, t[1] = b, t[2] = c, t += 3;
            t[0] = b, t[1] = d, t[2] = c, t += 3;
        }
    }
    return m;
}

/* Frame f's rigid motion (a turn about y and x, a travel) applied to local point q. */
static void sphere_frame(int f, const float q[3], float out[3])
{
    const double ay = 0.012 * f, ax = 0.3 * sin(0.02 * f); /* about 0.7 rad/s at 60 Hz */
    const double x1 = cos(ay) * q[0] + sin(ay) * q[2], z1 = -sin(ay) * q[0] + cos(ay) * q[2];
    const double y2 = cos(ax) * q[1] - sin(ax) * z1, z2 = sin(ax) * q[1] + cos(ax) * z1;
    out[0] = (float)(x1 + 0.3 * sin(0.07 * f));
    out[1] = (float)(y2 + 1.0 + 0.004 * f);
    out[2] = (float)(z2 - 0.1 * cos(0.03 * f));
}

static uint32_t lcg(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return *s >> 8;
}

static float unit_rand(uint32_t *s)
{
    return (float)lcg(s) / 16777216.0f * 2.0f - 1.0f;
}

static void test_push_clearance_matches_the_search(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh dirs = unit_sphere(48, 24), cloth = test_sheet(24, 20, 0.5f, 0.5f, 0.0f, 1.0f, 0.0f);
    const uint32_t nc = dirs.nv, n = cloth.nv;
    float *col = malloc(sizeof(float) * 3 * nc), *pts = malloc(sizeof(float) * 3 * n);
    float *local = malloc(sizeof(float) * 4 * n); /* direction, offset from the surface */
    uint32_t seed = 12345u;
    for (uint32_t v = 0; v < n; ++v) {
        float d[3], len;
        do {
            d[0] = unit_rand(&seed), d[1] = unit_rand(&seed), d[2] = unit_rand(&seed);
            len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        } while (len > 1.0f || len < 0.1f);
        local[4 * v] = d[0] / len, local[4 * v + 1] = d[1] / len, local[4 * v + 2] = d[2] / len;
        /* an eighth each inside within the push's depth, deeper, and beyond the search's radius;
         * the rest 1 .. 5 cm out */
        const float start[3] = {-0.01f, -0.09f, 0.12f};
        local[4 * v + 3] = v % 8 < 3 ? start[v % 8] : 0.02f * unit_rand(&seed) + 0.03f;
    }
    /* The sphere of frame f: radius 0.15 m breathing by 4 % along a wave over its surface; the
     * cloth points at their offsets from a sphere of the mean radius. */
    const float radius = 0.15f;
    weft_garment *g[2] = {NULL, NULL};
    uint64_t searched = 0, pushed = 0;
    for (int f = 0; f <= 240; ++f) {
        for (uint32_t i = 0; i < nc; ++i) {
            const float *u = dirs.pos + 3 * i;
            const float r = radius * (1.0f + 0.04f * sinf(3.0f * u[1] + 0.1f * (float)f));
            const float q[3] = {r * u[0], r * u[1], r * u[2]};
            sphere_frame(f, q, col + 3 * i);
        }
        for (uint32_t v = 0; v < n; ++v) {
            float *l = local + 4 * v;
            if (f > 0) { /* a wander of up to 2 mm a frame, kept within -11 .. 15 cm */
                l[3] = fminf(fmaxf(l[3] + 0.002f * unit_rand(&seed), -0.11f), 0.15f);
            }
            const float q[3] = {(radius + l[3]) * l[0], (radius + l[3]) * l[1], (radius + l[3]) * l[2]};
            sphere_frame(f, q, pts + 3 * v);
        }
        if (f == 0) {
            for (int k = 0; k < 2; ++k) {
                weft_garment_def gd = weft_default_garment_def();
                gd.method = WEFT_METHOD_EXTERNAL;
                gd.ccd.enabled = false;
                gd.rest_positions = cloth.pos;
                gd.vertex_count = n;
                gd.triangles = cloth.tris;
                gd.triangle_count = cloth.nt;
                gd.initial_positions = pts;
                gd.collider_rest_positions = col;
                gd.collider_vertex_count = nc;
                gd.collider_triangles = dirs.tris;
                gd.collider_triangle_count = dirs.nt;
                gd.collision.push = 0.005f; /* the worn recipe's: 0.5 cm from up to 6 cm deep */
                gd.collision.push_depth = 0.06f;
                CHECK_RESULT(weft_garment_create(ctx, &gd, &g[k]), WEFT_OK);
            }
            g[1]->near_search_all = true; /* the oracle */
            CHECK(g[0]->near_kcount > 16);
            continue;
        }
        for (int k = 0; k < 2; ++k) {
            CHECK_RESULT(weft_garment_set_collider(g[k], col), WEFT_OK);
            CHECK_RESULT(weft_garment_constrain(g[k], pts), WEFT_OK);
        }
        const weft_step_stats a = weft_garment_stats(g[0]), b = weft_garment_stats(g[1]);
        CHECK_EQ_INT((int)b.push_searched, (int)n);
        CHECK_EQ_INT((int)a.pushed_vertices, (int)b.pushed_vertices);
        CHECK_MSG(memcmp(weft_garment_positions(g[0]), weft_garment_positions(g[1]), sizeof(float) * 3 * n) == 0,
                  "frame %d: the clearance's push differs from the search's", f);
        searched += a.push_searched;
        pushed += a.pushed_vertices;
    }
    printf("clearance: %.1f %% of the vertex-steps searched, %.1f vertices pushed a step\n",
           100.0 * (double)searched / (240.0 * n), (double)pushed / 240.0);
    CHECK(pushed > 240); /* the push had work to do */
    CHECK(searched < 240u * n / 2);
    weft_garment_destroy(g[0]);
    weft_garment_destroy(g[1]);
    free(col);
    free(pts);
    free(local);
    test_mesh_free(&dirs);
    test_mesh_free(&cloth);
    weft_context_destroy(ctx);
}

static void test_push_bad_input(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh sheet = test_sheet(3, 3, 0.5f, 0.5f, 0.0f, 0.5f, 0.0f), box = test_box(k_lo, k_hi);
    const float bad[] = {-0.001f, NAN, INFINITY, 0.2f};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        CHECK(make(ctx, &sheet, &box, sheet.pos, bad[k], WEFT_ERROR_INVALID_ARGUMENT) == NULL);
        CHECK(strstr(weft_last_error(), "collision.push") != NULL);
    }
    weft_garment_def gd = push_def(&sheet, &box, NULL, 0.01f);
    weft_garment *g = NULL;
    const float bad_depth[] = {-0.01f, NAN, 0.6f};
    for (size_t k = 0; k < sizeof bad_depth / sizeof bad_depth[0]; ++k) {
        gd.collision.push_depth = bad_depth[k];
        CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(g == NULL);
        CHECK(strstr(weft_last_error(), "collision.push_depth") != NULL);
    }
    gd.collision.push_depth = 0.02f;
    gd.method = WEFT_METHOD_XPBD; /* LBS needs a collider anyway; XPBD does not */
    gd.collider_vertex_count = 0;
    gd.collider_rest_positions = NULL;
    gd.collider_triangles = NULL;
    gd.collider_triangle_count = 0;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_ERROR_NO_COLLIDER);
    CHECK(g == NULL);
    CHECK(strstr(weft_last_error(), "collision.push") != NULL);
    test_mesh_free(&box);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_push_matches_the_box_distance_field), TEST_CASE(test_push_sign_at_a_sharp_edge),
          TEST_CASE(test_push_with_ccd_lets_cloth_out), TEST_CASE(test_push_clearance_matches_the_search),
          TEST_CASE(test_push_bad_input))
