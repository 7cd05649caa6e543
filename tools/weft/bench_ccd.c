/* weft bench ccd: (1) average narrow-phase query time for vertex–face and edge–edge queries of
 * three kinds; (2) the full CCD post-process (all five types) of a 4096-vertex garment tube around a
 * procedural ~7k-triangle closed body (ellipsoid torso, head, arms, legs) at a typical frame, one
 * core. docs/CCD.md records the figures. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include "core/core.h"
#include "weft/ccd.h"

#include "support_cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* CPU time of the calling thread: the benchmark host may be shared, and wall time would then count
 * other processes' time slices. */
static double cpu_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

const char weft_bench_ccd_help[] = "CCD narrow-phase us/query and post-process ms/frame (4k garment, 7k body)";

typedef struct rng {
    uint64_t s;
} rng;

static double urand(rng *r)
{
    r->s ^= r->s << 13;
    r->s ^= r->s >> 7;
    r->s ^= r->s << 17;
    return (double)(r->s >> 11) / 9007199254740992.0;
}

typedef struct bmesh {
    float *x;
    uint32_t *t;
    uint32_t nv, nt;
} bmesh;

/* Closed ellipsoid (UV sphere with shared poles) appended to m (arrays sized by the caller). */
static void add_ellipsoid(bmesh *m, const float c[3], const float rad[3], uint32_t rings, uint32_t segs)
{
    uint32_t base = m->nv;
    float *p = m->x + 3 * (size_t)m->nv;
    p[0] = c[0], p[1] = c[1] + rad[1], p[2] = c[2];
    p[3] = c[0], p[4] = c[1] - rad[1], p[5] = c[2];
    m->nv += 2;
    for (uint32_t i = 1; i < rings; ++i) {
        double th = 3.14159265358979 * i / rings;
        for (uint32_t j = 0; j < segs; ++j) {
            double ph = 2 * 3.14159265358979 * j / segs;
            float *q = m->x + 3 * (size_t)m->nv++;
            q[0] = c[0] + (float)(rad[0] * sin(th) * cos(ph));
            q[1] = c[1] + (float)(rad[1] * cos(th));
            q[2] = c[2] + (float)(rad[2] * sin(th) * sin(ph));
        }
    }
#define V(i, j) (base + 2 + ((i) - 1) * segs + ((j) % segs))
    for (uint32_t j = 0; j < segs; ++j) {
        uint32_t *t = m->t + 3 * (size_t)m->nt;
        t[0] = base, t[1] = V(1, j + 1), t[2] = V(1, j);
        t[3] = base + 1, t[4] = V(rings - 1, j), t[5] = V(rings - 1, j + 1);
        m->nt += 2;
    }
    for (uint32_t i = 1; i + 1 < rings; ++i) {
        for (uint32_t j = 0; j < segs; ++j) {
            uint32_t *t = m->t + 3 * (size_t)m->nt;
            t[0] = V(i, j), t[1] = V(i, j + 1), t[2] = V(i + 1, j);
            t[3] = V(i, j + 1), t[4] = V(i + 1, j + 1), t[5] = V(i + 1, j);
            m->nt += 2;
        }
    }
#undef V
}

/* Torso, head, two arms, two legs: 7152 triangles. */
static bmesh make_body(void)
{
    bmesh m = {malloc(sizeof(float) * 3 * 8000), malloc(sizeof(uint32_t) * 3 * 16000), 0, 0};
    add_ellipsoid(&m, (const float[3]){0.0f, 1.2f, 0.0f}, (const float[3]){0.17f, 0.3f, 0.11f}, 40, 48);
    add_ellipsoid(&m, (const float[3]){0.0f, 1.65f, 0.0f}, (const float[3]){0.1f, 0.1f, 0.1f}, 16, 24);
    for (int s = -1; s <= 1; s += 2) {
        add_ellipsoid(&m, (const float[3]){0.3f * (float)s, 1.3f, 0.0f}, (const float[3]){0.2f, 0.05f, 0.05f}, 16, 24);
        add_ellipsoid(&m, (const float[3]){0.09f * (float)s, 0.55f, 0.0f}, (const float[3]){0.07f, 0.4f, 0.07f}, 14,
                      24);
    }
    return m;
}

/* A 64 x 64 tube 12 mm outside the torso between y = 0.95 and 1.22: 4096 vertices. */
static bmesh make_garment(void)
{
    enum { RINGS = 64, SEGS = 64 };
    bmesh m = {malloc(sizeof(float) * 3 * RINGS * SEGS), malloc(sizeof(uint32_t) * 6 * RINGS * SEGS), 0, 0};
    for (uint32_t i = 0; i < RINGS; ++i) {
        float y = 0.95f + 0.27f * (float)i / (RINGS - 1);
        float s = sqrtf(1.0f - ((y - 1.2f) / 0.3f) * ((y - 1.2f) / 0.3f));
        for (uint32_t j = 0; j < SEGS; ++j) {
            double ph = 2 * 3.14159265358979 * j / SEGS;
            float *p = m.x + 3 * (size_t)m.nv++;
            p[0] = (float)((0.17f * s + 0.012f) * cos(ph));
            p[1] = y;
            p[2] = (float)((0.11f * s + 0.012f) * sin(ph));
        }
    }
    for (uint32_t i = 0; i + 1 < RINGS; ++i) {
        for (uint32_t j = 0; j < SEGS; ++j) {
            uint32_t a = i * SEGS + j, b = i * SEGS + (j + 1) % SEGS, c = a + SEGS, d = b + SEGS;
            uint32_t *t = m.t + 3 * (size_t)m.nt;
            t[0] = a, t[1] = c, t[2] = b, t[3] = b, t[4] = c, t[5] = d;
            m.nt += 2;
        }
    }
    return m;
}

/* Queries of a given kind: 0 random in the unit cube with unit motion, 1 broad-phase-like (1 cm
 * primitives within 2 cm of each other, 1 cm motion), 2 crossing (a contact at a random t). */
static void make_queries(double *q, size_t n, int kind, rng *r)
{
    for (size_t k = 0; k < n; ++k) {
        double *P = q + 24 * k;
        double scale = kind == 1 ? 0.01 : 1.0;
        for (int i = 0; i < 12; ++i) {
            P[i] = scale * (2 * urand(r) - 1);
            P[12 + i] = P[i] + scale * (2 * urand(r) - 1);
        }
        if (kind == 2) {
            double ts = urand(r);
            for (int c = 0; c < 3; ++c) {
                double a = P[3 + c] + ts * (P[15 + c] - P[3 + c]), b = P[6 + c] + ts * (P[18 + c] - P[6 + c]);
                double d = P[9 + c] + ts * (P[21 + c] - P[9 + c]);
                double target = (a + b + d) / 3;
                P[12 + c] = ts > 0 ? P[c] + (target - P[c]) / ts : target;
            }
        }
    }
}

static void bench_narrow(size_t n, int reps)
{
    static const char *const names[3] = {"random unit cube", "broad-phase-like 1 cm", "crossing"};
    double *q = malloc(sizeof(double) * 24 * n);
    rng r = {0x9e3779b97f4a7c15ull};
    printf("narrow phase (%zu queries, best of %d repetitions, thread CPU time)\n", n, reps);
    printf("  %-24s %10s %10s %10s %10s\n", "kind", "vf us", "vf hits%", "ee us", "ee hits%");
    for (int kind = 0; kind < 3; ++kind) {
        make_queries(q, n, kind, &r);
        double us[2], rate[2];
        for (int type = 0; type < 2; ++type) {
            size_t hits = 0;
            double best = INFINITY;
            for (int rep = 0; rep < reps; ++rep) {
                hits = 0;
                double t0 = cpu_ms();
                for (size_t k = 0; k < n; ++k) {
                    double toi;
                    hits += (size_t)(type == 0 ? weft_ccd_vertex_face(q + 24 * k, 0, &toi)
                                               : weft_ccd_edge_edge(q + 24 * k, 0, &toi));
                }
                double ms = cpu_ms() - t0;
                best = ms < best ? ms : best;
            }
            us[type] = 1e3 * best / (double)n;
            rate[type] = 100.0 * (double)hits / (double)n;
        }
        printf("  %-24s %10.4f %10.2f %10.4f %10.2f\n", names[kind], us[0], rate[0], us[1], rate[1]);
    }
    free(q);
}

typedef struct scenario {
    const char *name;
    float noise;    /* cloth end positions: uniform noise of +-noise metres per coordinate */
    float fraction; /* fraction of vertices predicted `depth` metres inwards */
    float depth;
} scenario;

static int bench_postprocess(int frames, const scenario *sc)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cd, &ctx) != WEFT_OK) {
        fprintf(stderr, "weft bench ccd: %s\n", weft_last_error());
        return 1;
    }
    bmesh body = make_body(), cloth = make_garment();
    weft_ccd_world_def def = weft_default_ccd_world_def();
    def.cloth_triangles = cloth.t;
    def.cloth_triangle_count = cloth.nt;
    def.cloth_vertex_count = cloth.nv;
    def.cloth_layout_positions = cloth.x;
    def.collider_triangles = body.t;
    def.collider_triangle_count = body.nt;
    def.collider_vertex_count = body.nv;
    def.collider_layout_positions = body.x;
    weft_ccd_world *w = NULL;
    printf("post-process, %s frame (noise %.1f mm, %.0f%% of vertices %.0f mm inside): garment %u vertices / %u "
           "triangles, body %u vertices / %u triangles, thread CPU time\n",
           sc->name, 1e3 * sc->noise, 100.0 * sc->fraction, 1e3 * sc->depth, cloth.nv, cloth.nt, body.nv, body.nt);
    if (weft_ccd_world_create(ctx, &def, &w) != WEFT_OK) {
        fprintf(stderr, "weft bench ccd: %s\n", weft_last_error());
        weft_context_destroy(ctx);
        return 1;
    }
    /* The body moves 1 cm; the cloth follows with noise, and a fraction of its vertices is predicted
     * inside the body (penetrations the post-process must undo). */
    size_t n3 = (size_t)cloth.nv * 3, c3 = (size_t)body.nv * 3;
    float *c1 = malloc(sizeof(float) * c3), *x1 = malloc(sizeof(float) * n3), *work = malloc(sizeof(float) * n3);
    const float move[3] = {0.008f, 0.002f, 0.006f};
    for (size_t i = 0; i < c3; ++i) {
        c1[i] = body.x[i] + move[i % 3];
    }
    rng r = {12345};
    for (uint32_t v = 0; v < cloth.nv; ++v) {
        bool inward = urand(&r) < sc->fraction;
        float *p = x1 + 3 * (size_t)v;
        const float *p0 = cloth.x + 3 * (size_t)v;
        float rad = sqrtf(p0[0] * p0[0] + p0[2] * p0[2]);
        for (int k = 0; k < 3; ++k) {
            p[k] = p0[k] + move[k] + sc->noise * (float)(2 * urand(&r) - 1);
        }
        if (inward) {
            p[0] -= sc->depth * p0[0] / rad;
            p[2] -= sc->depth * p0[2] / rad;
        }
    }
    weft_ccd_report rep;
    weft_ccd_metrics before, after;
    static const char *const type_names[5] = {"vf", "ee", "fv", "self-vf", "self-ee"};
    printf("  detect per type (one pass, best of %d):\n", frames);
    for (int type = 0; type < 5; ++type) {
        double best = INFINITY;
        for (int f = 0; f < frames; ++f) {
            double t0 = cpu_ms();
            weft_ccd_detect(w, cloth.x, x1, body.x, c1, WEFT_CCD_MASK(type), &rep);
            double ms = cpu_ms() - t0;
            best = ms < best ? ms : best;
        }
        printf("    %-8s %8.3f ms  %8llu narrow tests  %5u hits\n", type_names[type], best,
               (unsigned long long)rep.narrow_tests, rep.hit_total);
    }
    weft_ccd_compute_metrics(w, cloth.x, x1, body.x, c1, &before);
    double detect_ms = INFINITY;
    for (int f = 0; f < frames; ++f) {
        double t0 = cpu_ms();
        weft_ccd_detect(w, cloth.x, x1, body.x, c1, WEFT_CCD_MASK_ALL, &rep);
        double ms = cpu_ms() - t0;
        detect_ms = ms < detect_ms ? ms : detect_ms;
    }
    /* A clean frame (no penetration): one detect pass is the whole post-process. */
    for (size_t i = 0; i < n3; ++i) {
        work[i] = cloth.x[i] + move[i % 3];
    }
    weft_ccd_postprocess_stats st;
    double clean_ms = INFINITY;
    for (int f = 0; f < frames; ++f) {
        double t0 = cpu_ms();
        weft_ccd_postprocess(w, cloth.x, work, body.x, c1, &st);
        double ms = cpu_ms() - t0;
        clean_ms = ms < clean_ms ? ms : clean_ms;
    }
    uint32_t clean_iters = st.iterations;
    double post_ms = INFINITY, post_sum = 0.0;
    for (int f = 0; f < frames; ++f) {
        memcpy(work, x1, sizeof(float) * n3);
        double t0 = cpu_ms();
        weft_ccd_postprocess(w, cloth.x, work, body.x, c1, &st);
        double ms = cpu_ms() - t0;
        post_sum += ms;
        post_ms = ms < post_ms ? ms : post_ms;
    }
    weft_ccd_compute_metrics(w, cloth.x, work, body.x, c1, &after);
    weft_ccd_intersections in;
    weft_ccd_intersect_frame(w, work, c1, &in);
    printf("  detect, all 5 types (one pass):    %8.3f ms  (%llu narrow tests, %u hits: vf %u ee %u fv %u "
           "self-vf %u self-ee %u)\n",
           detect_ms, (unsigned long long)rep.narrow_tests, rep.hit_total, rep.hits[0], rep.hits[1], rep.hits[2],
           rep.hits[3], rep.hits[4]);
    printf("  post-process, rigidly following:   %8.3f ms  (%u pass)\n", clean_ms, clean_iters);
    printf("  post-process, this frame:          %8.3f ms min, %.3f ms mean  (%u passes, %u vertices moved, "
           "fallback %d)\n",
           post_ms, post_sum / frames, st.iterations, st.vertices_moved, (int)st.fallback);
    printf("  collision rate %.2f%% -> %.2f%%, self-collision rate %.2f%% -> %.2f%%, "
           "intersecting triangle pairs after: %u cloth-cloth, %u cloth-body\n",
           before.collision_rate, after.collision_rate, before.self_collision_rate, after.self_collision_rate,
           in.cloth_cloth, in.cloth_collider);
    weft_ccd_world_destroy(w);
    free(c1);
    free(x1);
    free(work);
    free(body.x);
    free(body.t);
    free(cloth.x);
    free(cloth.t);
    weft_context_destroy(ctx);
    return 0;
}

enum { OPT_QUERIES = 1, OPT_FRAMES };

static const cli_option k_options[] = {
    /* 10^7 queries hold 1.9 GB of coordinates */
    {"queries", "N", OPT_QUERIES, "narrow-phase queries of each kind, 1..10000000 (default 200000)"},
    {"frames", "N", OPT_FRAMES,
     "post-process repetitions per scenario (best / mean of them), 1..100000\n"
     "(default 20)"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft bench ccd",
    .synopsis = "weft bench ccd [--queries N] [--frames N]",
    .about = "CCD narrow-phase us/query (vertex-face and edge-edge, three kinds of query) and the full\n"
             "post-process ms/frame of a 4096-vertex garment around a ~7k-triangle body, one core, thread CPU\n"
             "time (docs/CCD.md records the figures).",
    .options = k_options,
    .notes = NULL,
};

int weft_bench_ccd(int argc, char **argv);
int weft_bench_ccd(int argc, char **argv)
{
    uint32_t queries = 200000, frames = 20;
    cli_parser parser;
    cli_start(&parser, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&parser, &v)) != CLI_END;) {
        switch (id) {
        case CLI_STOP:
            return parser.exit;
        case OPT_QUERIES:
            if (!cli_u32(k_command.tool, cli_name(&k_command, id), v, 1, 10000000, &queries)) {
                return 2;
            }
            break;
        case OPT_FRAMES:
            if (!cli_u32(k_command.tool, cli_name(&k_command, id), v, 1, 100000, &frames)) {
                return 2;
            }
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&parser) != 0) {
        return 2;
    }
    printf("# %s\n", weft_config_string());
    bench_narrow(queries, 3);
    static const scenario scenarios[2] = {{"typical", 0.001f, 0.01f, 0.02f}, {"stress", 0.004f, 0.02f, 0.02f}};
    int status = 0;
    for (int i = 0; i < 2 && status == 0; ++i) {
        status = bench_postprocess((int)frames, &scenarios[i]);
    }
    return status;
}
