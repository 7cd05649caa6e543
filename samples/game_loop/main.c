/*
 * game_loop — the smallest complete use of weft in a game loop.
 *
 * A 1 m cloth sheet hangs above a ball that rises into it, sways and falls away again; every
 * frame the host
 *   1. moves its collider to where it will be at the next frame,
 *   2. hands it to weft (weft_garment_set_collider),
 *   3. steps the cloth one 1/60 s frame (weft_garment_step),
 *   4. reads the positions back (weft_garment_positions) to draw them,
 * and prints how long the step took. Only include/weft.h is used.
 *
 *   game_loop [--method xpbd|lbs|model] [--model FILE] [--frames N] [--grid N] [--quiet]
 *
 * --frames takes 1..100000 (default 120), --grid 2..512 vertices a side (default 32); anything
 * else, or a value with trailing text, is refused with exit status 2.
 *
 * Without --method it uses the first method this build provides, trying XPBD, then LBS.
 * A method the build lacks, or the model method without a model, fails with weft's message.
 */
#include "weft.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define BALL_RINGS 16
#define BALL_SEGMENTS 24

typedef struct mesh {
    float *positions;
    uint32_t *triangles;
    uint32_t vertex_count, triangle_count;
} mesh;

static void mesh_free(mesh *m)
{
    free(m->positions);
    free(m->triangles);
}

/* n x n grid sheet, `size` metres a side, in the XZ plane at height y, facing +Y. */
static int make_sheet(uint32_t n, float size, float y, mesh *m)
{
    m->vertex_count = n * n;
    m->triangle_count = 2 * (n - 1) * (n - 1);
    m->positions = malloc((size_t)m->vertex_count * 3 * sizeof(float));
    m->triangles = malloc((size_t)m->triangle_count * 3 * sizeof(uint32_t));
    if (!m->positions || !m->triangles) {
        return 0;
    }
    for (uint32_t j = 0; j < n; ++j) {
        for (uint32_t i = 0; i < n; ++i) {
            float *p = m->positions + 3 * ((size_t)j * n + i);
            p[0] = size * ((float)i / (float)(n - 1) - 0.5f);
            p[1] = y;
            p[2] = size * ((float)j / (float)(n - 1) - 0.5f);
        }
    }
    uint32_t *t = m->triangles;
    for (uint32_t j = 0; j + 1 < n; ++j) {
        for (uint32_t i = 0; i + 1 < n; ++i) {
            uint32_t a = j * n + i, b = a + 1, c = a + n, d = c + 1;
            t[0] = a, t[1] = c, t[2] = b, t[3] = b, t[4] = c, t[5] = d;
            t += 6;
        }
    }
    return 1;
}

/* Unit-radius UV ball with single-vertex poles, centred at the origin. */
static int make_ball(mesh *m)
{
    m->vertex_count = 2 + (BALL_RINGS - 1) * BALL_SEGMENTS;
    m->triangle_count = 2 * BALL_SEGMENTS * (BALL_RINGS - 1);
    m->positions = malloc((size_t)m->vertex_count * 3 * sizeof(float));
    m->triangles = malloc((size_t)m->triangle_count * 3 * sizeof(uint32_t));
    if (!m->positions || !m->triangles) {
        return 0;
    }
    const float pi = 3.14159265f;
    float *p = m->positions;
    p[0] = 0, p[1] = 1, p[2] = 0;
    for (uint32_t r = 1; r < BALL_RINGS; ++r) {
        float th = pi * (float)r / BALL_RINGS;
        for (uint32_t s = 0; s < BALL_SEGMENTS; ++s) {
            float ph = 2 * pi * (float)s / BALL_SEGMENTS;
            float *q = p + 3 * (1 + (size_t)(r - 1) * BALL_SEGMENTS + s);
            q[0] = sinf(th) * sinf(ph), q[1] = cosf(th), q[2] = sinf(th) * cosf(ph);
        }
    }
    float *bottom = p + 3 * (size_t)(m->vertex_count - 1);
    bottom[0] = 0, bottom[1] = -1, bottom[2] = 0;
    uint32_t *t = m->triangles, last = 1 + (BALL_RINGS - 2) * BALL_SEGMENTS;
    for (uint32_t s = 0; s < BALL_SEGMENTS; ++s) {
        uint32_t s1 = (s + 1) % BALL_SEGMENTS;
        t[0] = 0, t[1] = 1 + s, t[2] = 1 + s1;
        t += 3;
    }
    for (uint32_t r = 1; r + 1 < BALL_RINGS; ++r) {
        uint32_t a0 = 1 + (r - 1) * BALL_SEGMENTS, b0 = 1 + r * BALL_SEGMENTS;
        for (uint32_t s = 0; s < BALL_SEGMENTS; ++s) {
            uint32_t s1 = (s + 1) % BALL_SEGMENTS;
            t[0] = a0 + s, t[1] = b0 + s, t[2] = b0 + s1, t[3] = a0 + s, t[4] = b0 + s1, t[5] = a0 + s1;
            t += 6;
        }
    }
    for (uint32_t s = 0; s < BALL_SEGMENTS; ++s) {
        uint32_t s1 = (s + 1) % BALL_SEGMENTS;
        t[0] = last + s, t[1] = m->vertex_count - 1, t[2] = last + s1;
        t += 3;
    }
    return 1;
}

/* The ball's path: rises into the sheet for the first half, sways, then drops away. */
static void ball_at(uint32_t frame, uint32_t frames, const mesh *unit, float *out)
{
    float t = (float)frame / (float)(frames > 1 ? frames - 1 : 1);
    float radius = 0.25f;
    float lift = t < 0.5f ? 0.2f + 0.9f * (t / 0.5f) : 1.1f - 0.9f * ((t - 0.5f) / 0.5f);
    float sway = 0.15f * sinf(6.2831853f * 2.0f * t);
    for (uint32_t v = 0; v < unit->vertex_count; ++v) {
        const float *p = unit->positions + 3 * (size_t)v;
        out[3 * v + 0] = radius * p[0] + sway;
        out[3 * v + 1] = radius * p[1] + lift;
        out[3 * v + 2] = radius * p[2];
    }
}

static void usage(void)
{
    fprintf(stderr, "usage: game_loop [--method xpbd|lbs|model] [--model FILE] [--frames N (1..100000)]\n"
                    "                 [--grid N (2..512)] [--quiet]\n");
}

/* A whole number in [lo, hi] and nothing else: digits only (no sign, no spaces, no trailing
 * text), without overflow. Prints what it wanted and returns 0 otherwise, *out untouched. */
static int parse_count(const char *option, const char *s, uint32_t lo, uint32_t hi, uint32_t *out)
{
    uint64_t v = 0;
    size_t n = 0;
    for (; s[n] >= '0' && s[n] <= '9' && v <= hi; ++n) {
        v = v * 10u + (uint64_t)(s[n] - '0');
    }
    if (n == 0 || s[n] != '\0' || v < lo || v > hi) {
        fprintf(stderr, "game_loop: %s wants a whole number in [%u, %u], got '%s'\n", option, lo, hi, s);
        return 0;
    }
    *out = (uint32_t)v;
    return 1;
}

int main(int argc, char **argv)
{
    const char *method_name = NULL, *model_path = NULL;
    uint32_t frames = 120, grid = 32;
    int quiet = 0;
    for (int i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--method") == 0 && i + 1 < argc) {
            method_name = argv[++i];
        } else if (strcmp(argv[i], "--model") == 0 && i + 1 < argc) {
            model_path = argv[++i];
        } else if (strcmp(argv[i], "--frames") == 0 && i + 1 < argc) {
            if (!parse_count(argv[i], argv[i + 1], 1, 100000, &frames)) {
                return 2;
            }
            ++i;
        } else if (strcmp(argv[i], "--grid") == 0 && i + 1 < argc) {
            if (!parse_count(argv[i], argv[i + 1], 2, 512, &grid)) {
                return 2;
            }
            ++i;
        } else if (strcmp(argv[i], "--quiet") == 0) {
            quiet = 1;
        } else {
            usage();
            return 2;
        }
    }
    weft_context_def cdef = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cdef, &ctx) != WEFT_OK) {
        fprintf(stderr, "game_loop: weft_context_create: %s\n", weft_last_error());
        return 1;
    }
    printf("%s\n", weft_config_string());

    weft_model *model = NULL;
    if (model_path && weft_model_load_file(ctx, model_path, &model) != WEFT_OK) {
        fprintf(stderr, "game_loop: cannot load model '%s': %s\n", model_path, weft_last_error());
        weft_context_destroy(ctx);
        return 1;
    }

    mesh sheet = {0}, ball = {0};
    float *ball_now = NULL;
    int ok = make_sheet(grid, 1.0f, 1.2f, &sheet) && make_ball(&ball);
    ball_now = ok ? malloc((size_t)ball.vertex_count * 3 * sizeof(float)) : NULL;
    if (!ok || !ball_now) {
        fprintf(stderr, "game_loop: out of memory\n");
        mesh_free(&sheet);
        mesh_free(&ball);
        weft_model_destroy(model);
        weft_context_destroy(ctx);
        return 1;
    }
    ball_at(0, frames, &ball, ball_now);

    static const struct {
        const char *name;
        weft_method method;
    } methods[] = {{"xpbd", WEFT_METHOD_XPBD}, {"lbs", WEFT_METHOD_LBS}, {"model", WEFT_METHOD_MODEL}};
    weft_garment *garment = NULL;
    const char *used = NULL;
    for (size_t m = 0; m < sizeof methods / sizeof methods[0] && !garment; ++m) {
        if (method_name ? strcmp(method_name, methods[m].name) != 0 : methods[m].method == WEFT_METHOD_MODEL) {
            continue; /* without --method the model is not tried: it needs a model file */
        }
        weft_garment_def def = weft_default_garment_def();
        def.method = methods[m].method;
        def.model = model;
        def.rest_positions = sheet.positions;
        def.vertex_count = sheet.vertex_count;
        def.triangles = sheet.triangles;
        def.triangle_count = sheet.triangle_count;
        def.collider_rest_positions = ball_now;
        def.collider_vertex_count = ball.vertex_count;
        def.collider_triangles = ball.triangles;
        def.collider_triangle_count = ball.triangle_count;
        weft_result r = weft_garment_create(ctx, &def, &garment);
        if (r == WEFT_OK) {
            used = methods[m].name;
        } else {
            fprintf(stderr, "game_loop: method '%s': %s: %s\n", methods[m].name, weft_result_string(r), weft_last_error());
        }
    }
    if (!garment) {
        fprintf(stderr, "game_loop: no cloth method could be created%s%s\n", method_name ? " for --method " : "",
                method_name ? method_name : "");
        free(ball_now);
        mesh_free(&sheet);
        mesh_free(&ball);
        weft_model_destroy(model);
        weft_context_destroy(ctx);
        return 1;
    }
    printf("method %s, sheet %u vertices, ball collider %u vertices, %u frames\n", used, sheet.vertex_count,
           ball.vertex_count, frames);

    /* --- the game loop --- */
    double total_ms = 0, worst_ms = 0;
    int status = 0;
    for (uint32_t f = 1; f <= frames; ++f) {
        ball_at(f, frames, &ball, ball_now);                  /* 1. game logic moves the collider */
        weft_result r = weft_garment_set_collider(garment, ball_now); /* 2. collider at t+1 */
        if (r == WEFT_OK) {
            r = weft_garment_step(garment);                   /* 3. one 1/60 s frame */
        }
        if (r != WEFT_OK) {
            fprintf(stderr, "game_loop: frame %u: %s: %s\n", f, weft_result_string(r), weft_last_error());
            status = 1;
            break;
        }
        const float *x = weft_garment_positions(garment);     /* 4. draw these */
        weft_step_stats st = weft_garment_stats(garment);
        total_ms += st.step_ms;
        worst_ms = st.step_ms > worst_ms ? st.step_ms : worst_ms;
        if (!quiet) {
            float lowest = x[1];
            for (uint32_t v = 1; v < sheet.vertex_count; ++v) {
                lowest = x[3 * v + 1] < lowest ? x[3 * v + 1] : lowest;
            }
            printf("frame %4u  step %7.3f ms  ccd passes %u moved %u%s  lowest cloth y %.3f m\n", f, st.step_ms,
                   st.ccd_iterations, st.ccd_vertices_moved, st.ccd_fallback ? " (fallback)" : "", (double)lowest);
        }
    }
    if (status == 0) {
        printf("%u frames, mean step %.3f ms, worst %.3f ms (budget at 60 Hz: 16.7 ms per frame)\n", frames,
               total_ms / frames, worst_ms);
    }
    weft_garment_destroy(garment);
    free(ball_now);
    mesh_free(&sheet);
    mesh_free(&ball);
    weft_model_destroy(model);
    weft_context_destroy(ctx);
    return status;
}
