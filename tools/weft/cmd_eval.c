/* weft eval: autoregressive rollout of a method over simgen sequences, scored against the
 * ground truth. The rollout starts from the first two ground-truth frames (positions at frames 0
 * and 1) and then only sees the collider; every later frame is the method's own output.
 *
 *   mve_cm               mean Euclidean vertex error over all vertices and predicted frames (cm)
 *   collision_rate       % cloth vertices inside or crossing the collider per frame (mean)
 *   self_collision_rate  % cloth vertices in self vertex-face / edge-edge CCD hits per frame (mean)
 *   ms_per_frame         wall time of weft_garment_step (includes CCD post-processing when on)
 *   frames               predicted frames scored
 *   nan                  the method produced a non-finite state (the rollout stops there)
 *   max_edge_strain      max over edges and frames of |length / rest length - 1|
 *   overstretched_pct    max over frames of the % of edges strained by more than 25%: one edge at a
 *                        pinned waistband can pass 25% while the garment is fine; an exploding one
 *                        overstretches many
 *   gt_max_edge_strain   the ground truth's own max edge strain over the same frames (context for
 *                        the two above: the reference stretches too, at pins and tight contacts)
 *   time_limited         --time-limit stopped the rollout before its last frame
 *   ms_p50/p99/max       percentiles of the step's wall time over the scored frames
 *   wear                 worn garments (meta.json scenario "garment"), tools/lab/include/weft/wear.h, against
 *                        the garment carried by the skin (weft_garment_skinned_positions): frames
 *                        with off_body over 1 % (a sequence with any has lost the garment; off_body
 *                        is the share farther than 10 cm, 25 cm for skirts and dresses), the worst
 *                        off_body, inside_body mean / max, body_self_overlap mean / max; not with
 *                        --sim-mesh */
#define _POSIX_C_SOURCE 200809L /* opendir, stat */
#include "weft.h"
#include "weft/ccd.h"
#include "weft/lod.h"
#include "weft/sim.h"
#include "assets/npz.h"
#include "npy_write.h"
#include "support_bench.h"
#include "support_cli.h"

#include <cjson/cJSON.h>
#if WEFT_HAVE_RENDER
#include "weft/wear.h"
#endif
#if WEFT_RENDER_HAVE_SAMPLE
#include "weft_sample.h"
#endif
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

int weft_cmd_eval(int argc, char **argv); /* the CLI registry declares it in main.c */

const char weft_cmd_eval_help[] = "score a method's rollout against simgen sequences (MVE, collisions, timing)";

typedef struct eval_opts {
    const char *model_path, *seq, *split;
    weft_method method;
    uint32_t substeps;
    weft_precision precision;
    bool ccd, json;
    uint32_t ccd_iterations;            /* weft_garment_def.ccd.iterations */
    uint32_t max_frames;
    float crop_margin;                  /* m, 0: the model's own */
    weft_collider_crop crop;
    uint32_t max_collider_tokens;
    weft_collider_cap collider_cap;
    float tether;                       /* m, 0: no tethers */
    float strain_limit;                 /* fraction, 0: off */
    float strain_contact;               /* metres, 0: off (weft_garment_def.strain.contact) */
    float push, push_depth;             /* metres (weft_garment_def.collision.push, collision.push_depth) */
    const char *sim_mesh;               /* folder with rest_pos.npy + faces.npy: simulate on this mesh */
    const char *write_pos;              /* folder: write each rollout as <sequence>.npy [frames + 2, N, 3] */
    bool pins_all;                      /* the sequence's pins for every method, not only XPBD */
    double time_limit_ms;               /* 0: none; else stop a rollout once stepping took this long */
    bool recipe_worn;                   /* worn garments get the worn-garment recipe (--recipe worn) */
} eval_opts;

typedef struct eval_acc {
    double err_sum;          /* sum of per-vertex errors (m) */
    double vert_frames;      /* vertices x frames scored */
    double coll_sum, self_sum;
    uint32_t metric_frames;
    double ms_sum;
    double tokens_sum;                  /* collider tokens kept by the model's crop, summed per frame */
    double ccd_passes_sum;              /* CCD post-process passes, summed per frame */
    double pushed_sum;                  /* vertices the collider push moved, summed per frame */
    double let_out_sum;                 /* vertices CCD let out of the collider, summed per frame */
    double push_far_sum;               /* vertices it found inside and left, summed per frame */
    uint32_t frames;
    bool nan;
    double max_strain, gt_max_strain;
    double overstretched_pct;           /* max over frames of % edges strained > EVAL_OVERSTRETCH */
    uint32_t sequences;
    bool metrics_ok;
    bool time_limited;
#if WEFT_HAVE_RENDER
    weft_wear_summary wear;             /* worn garments only */
#endif
    uint32_t worn_sequences, lost_sequences;
    double *frame_ms;                   /* per scored frame (percentiles) */
    uint32_t frame_ms_count, frame_ms_cap;
} eval_acc;

static void push_frame_ms(eval_acc *a, double ms)
{
    if (a->frame_ms_count == a->frame_ms_cap) {
        uint32_t cap = a->frame_ms_cap ? 2 * a->frame_ms_cap : 256;
        double *grown = realloc(a->frame_ms, cap * sizeof *grown);
        if (!grown) {
            return; /* the percentiles then cover the frames kept */
        }
        a->frame_ms = grown;
        a->frame_ms_cap = cap;
    }
    a->frame_ms[a->frame_ms_count++] = ms;
}

/* The p-th percentile of the step times as JSON ("null" without the wear measures' library,
 * whose weft_wear_percentile computes it, or without frames). Sorts the times in place. */
static const char *ms_percentile(eval_acc *a, double p, char *out, size_t cap)
{
    snprintf(out, cap, "null");
#if WEFT_HAVE_RENDER
    if (a->frame_ms_count > 0) {
        snprintf(out, cap, "%.6g", weft_wear_percentile(a->frame_ms, a->frame_ms_count, p));
    }
#else
    (void)a, (void)p;
#endif
    return out;
}

/* A worn garment (meta.json scenario "garment"): its kind (skirt or dress when the description
 * names one, else a T-shirt) and off-body distance, 25 cm for skirts and dresses, else 10 cm.
 * False for other scenarios. */
static bool worn_garment(const char *dir, float *off_distance, weft_cloth_kind *kind)
{
    char path[1200];
    snprintf(path, sizeof path, "%s/meta.json", dir);
    FILE *f = fopen(path, "rb");
    if (!f) {
        return false;
    }
    char buf[65536];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    cJSON *meta = cJSON_Parse(buf);
    const cJSON *scenario = cJSON_GetObjectItemCaseSensitive(meta, "scenario");
    const cJSON *desc = cJSON_GetObjectItemCaseSensitive(meta, "description");
    const bool worn = cJSON_IsString(scenario) && strcmp(scenario->valuestring, "garment") == 0;
    const bool skirt = cJSON_IsString(desc) && strstr(desc->valuestring, "skirt");
    const bool dress = cJSON_IsString(desc) && strstr(desc->valuestring, "dress");
    *off_distance = skirt || dress ? 0.25f : 0.10f;
    *kind = skirt ? WEFT_CLOTH_SKIRT : dress ? WEFT_CLOTH_DRESS : WEFT_CLOTH_TSHIRT;
    cJSON_Delete(meta);
    return worn;
}

#define EVAL_OVERSTRETCH 0.25

typedef struct seq_data {
    float *rest, *pos, *cpos;
    float *pinned;                      /* [T, V] 0/1, optional: vertices attached to a gripper */
    uint32_t *faces, *cfaces;
    uint32_t V, F, T, Vc, Fc;
} seq_data;

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

/* dir/name into out; false (and nothing usable) when it does not fit. */
static bool path_join(char *out, size_t cap, const char *dir, const char *name)
{
    int n = snprintf(out, cap, "%s/%s", dir, name);
    return n >= 0 && (size_t)n < cap;
}

static void *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    void *p = NULL;
    if (fseek(f, 0, SEEK_END) == 0) {
        long n = ftell(f);
        if (n >= 0 && fseek(f, 0, SEEK_SET) == 0) {
            p = malloc((size_t)n + 1);
            if (p && fread(p, 1, (size_t)n, f) != (size_t)n) {
                free(p);
                p = NULL;
            }
            *size = (size_t)n;
            if (p) {
                ((char *)p)[n] = '\0';
            }
        }
    }
    fclose(f);
    return p;
}

/* Loads dir/name.npy as float32 (want_int: as uint32 indices) with the given rank. */
static weft_result load_npy(const char *dir, const char *name, uint32_t rank, bool want_int, void **out,
                            uint64_t shape[3], bool optional)
{
    char path[1024], file[160];
    size_t size = 0;
    int fl = snprintf(file, sizeof file, "%s.npy", name);
    void *bytes = fl > 0 && (size_t)fl < sizeof file && path_join(path, sizeof path, dir, file) ? slurp(path, &size)
                                                                                              : NULL;
    if (!bytes) {
        if (optional) {
            *out = NULL;
            return WEFT_OK;
        }
        fprintf(stderr, "weft eval: cannot read %s\n", path);
        return WEFT_ERROR_IO;
    }
    weft_npy_array a;
    weft_result r = weft_npy_parse(bytes, size, name, &a);
    if (r == WEFT_OK && a.ndim != rank) {
        fprintf(stderr, "weft eval: %s has %u dimensions, expected %u\n", path, a.ndim, rank);
        r = WEFT_ERROR_SIZE_MISMATCH;
    }
    if (r == WEFT_OK && (a.shape[rank - 1] != 3 || a.count == 0 || a.count > (1ull << 31))) {
        fprintf(stderr, "weft eval: %s: last dimension must be 3 and the array non-empty\n", path);
        r = WEFT_ERROR_SIZE_MISMATCH;
    }
    if (r == WEFT_OK) {
        for (uint32_t i = 0; i < rank; ++i) {
            shape[i] = a.shape[i];
        }
        if (want_int) {
            int64_t *tmp = malloc(a.count * sizeof(int64_t));
            uint32_t *idx = malloc(a.count * sizeof(uint32_t));
            r = tmp && idx ? weft_npy_to_i64(&a, tmp, a.count) : WEFT_ERROR_OUT_OF_MEMORY;
            for (uint64_t i = 0; r == WEFT_OK && i < a.count; ++i) {
                if (tmp[i] < 0 || tmp[i] > (int64_t)UINT32_MAX) {
                    fprintf(stderr, "weft eval: %s: index %lld out of range\n", path, (long long)tmp[i]);
                    r = WEFT_ERROR_FORMAT;
                }
                idx[i] = (uint32_t)tmp[i];
            }
            free(tmp);
            if (r == WEFT_OK) {
                *out = idx;
            } else {
                free(idx);
            }
        } else {
            float *f = malloc(a.count * sizeof(float));
            r = f ? weft_npy_to_f32(&a, f, a.count) : WEFT_ERROR_OUT_OF_MEMORY;
            if (r == WEFT_OK) {
                *out = f;
            } else {
                free(f);
            }
        }
        if (r != WEFT_OK && r != WEFT_ERROR_FORMAT && r != WEFT_ERROR_OUT_OF_MEMORY) {
            fprintf(stderr, "weft eval: %s: %s\n", path, weft_last_error());
        }
    } else if (r != WEFT_ERROR_SIZE_MISMATCH) {
        fprintf(stderr, "weft eval: %s: %s\n", path, weft_last_error());
    }
    free(bytes);
    return r;
}

/* Optional pinned.npy [T, V] (any numeric dtype, non-zero = pinned) as floats. */
static float *load_pinned(const char *dir, uint32_t T, uint32_t V)
{
    char path[1024];
    size_t size = 0;
    void *bytes = path_join(path, sizeof path, dir, "pinned.npy") ? slurp(path, &size) : NULL;
    if (!bytes) {
        return NULL;
    }
    weft_npy_array a;
    float *out = NULL;
    if (weft_npy_parse(bytes, size, "pinned", &a) == WEFT_OK && a.ndim == 2 && a.shape[0] == T && a.shape[1] == V) {
        out = malloc(a.count * sizeof(float));
        if (out && weft_npy_to_f32(&a, out, a.count) != WEFT_OK) {
            free(out);
            out = NULL;
        }
    } else {
        fprintf(stderr, "weft eval: %s: expected [%u, %u] pins, ignored\n", path, T, V);
    }
    free(bytes);
    return out;
}

static void seq_free(seq_data *s)
{
    free(s->pinned);
    free(s->rest);
    free(s->pos);
    free(s->cpos);
    free(s->faces);
    free(s->cfaces);
    memset(s, 0, sizeof *s);
}

static weft_result seq_load(const char *dir, seq_data *s)
{
    memset(s, 0, sizeof *s);
    uint64_t sr[3] = {0}, sf[3] = {0}, sp[3] = {0}, sc[3] = {0}, scf[3] = {0};
    weft_result r;
    if ((r = load_npy(dir, "rest_pos", 2, false, (void **)&s->rest, sr, false)) ||
        (r = load_npy(dir, "faces", 2, true, (void **)&s->faces, sf, false)) ||
        (r = load_npy(dir, "cloth_pos", 3, false, (void **)&s->pos, sp, false)) ||
        (r = load_npy(dir, "collider_pos", 3, false, (void **)&s->cpos, sc, true)) ||
        (r = load_npy(dir, "collider_faces", 2, true, (void **)&s->cfaces, scf, true))) {
        seq_free(s);
        return r;
    }
    s->V = (uint32_t)sr[0];
    s->F = (uint32_t)sf[0];
    s->T = (uint32_t)sp[0];
    if (sp[1] != sr[0] || s->T < 3) {
        fprintf(stderr, "weft eval: %s: cloth_pos is [%llu, %llu, 3] but rest_pos has %u vertices (need >= 3 frames)\n",
                dir, (unsigned long long)sp[0], (unsigned long long)sp[1], s->V);
        seq_free(s);
        return WEFT_ERROR_SIZE_MISMATCH;
    }
    s->pinned = load_pinned(dir, s->T, s->V);
    if (s->cpos && s->cfaces) {
        s->Vc = (uint32_t)sc[1];
        s->Fc = (uint32_t)scf[0];
        if (sc[0] != sp[0]) {
            fprintf(stderr, "weft eval: %s: collider_pos has %llu frames, cloth_pos %u\n", dir,
                    (unsigned long long)sc[0], s->T);
            seq_free(s);
            return WEFT_ERROR_SIZE_MISMATCH;
        }
    } else {
        free(s->cpos);
        free(s->cfaces);
        s->cpos = NULL;
        s->cfaces = NULL;
    }
    return WEFT_OK;
}

/* Every triangle edge as a pair (interior edges appear twice, harmless for a maximum). */
static uint32_t *edges_of(const seq_data *s, uint32_t *count)
{
    uint32_t *e = malloc((size_t)s->F * 6 * sizeof(uint32_t));
    if (!e) {
        return NULL;
    }
    uint32_t n = 0;
    for (uint32_t t = 0; t < s->F; ++t) {
        for (int k = 0; k < 3; ++k) {
            uint32_t a = s->faces[3 * (size_t)t + k], b = s->faces[3 * (size_t)t + (k + 1) % 3];
            e[2 * n] = a < b ? a : b;
            e[2 * n + 1] = a < b ? b : a;
            n++;
        }
    }
    *count = n;
    return e;
}

/* Max |length / rest - 1| over the edges; *over counts the edges above EVAL_OVERSTRETCH. */
static double max_strain(const float *x, const float *rest, const uint32_t *e, uint32_t ne, uint32_t *over)
{
    double m = 0;
    uint32_t n = 0;
    for (uint32_t i = 0; i < ne; ++i) {
        const float *a = x + 3 * (size_t)e[2 * i], *b = x + 3 * (size_t)e[2 * i + 1];
        const float *ra = rest + 3 * (size_t)e[2 * i], *rb = rest + 3 * (size_t)e[2 * i + 1];
        double l = sqrt((double)(a[0] - b[0]) * (a[0] - b[0]) + (double)(a[1] - b[1]) * (a[1] - b[1]) +
                        (double)(a[2] - b[2]) * (a[2] - b[2]));
        double r = sqrt((double)(ra[0] - rb[0]) * (ra[0] - rb[0]) + (double)(ra[1] - rb[1]) * (ra[1] - rb[1]) +
                        (double)(ra[2] - rb[2]) * (ra[2] - rb[2]));
        if (r > 0) {
            double strain = fabs(l / r - 1.0);
            m = fmax(m, strain);
            n += strain > EVAL_OVERSTRETCH;
        }
    }
    if (over) {
        *over = n;
    }
    return m;
}

/* DIR/<sequence folder name>.npy, [frames, V, 3] float32. */
static bool write_rollout(const char *out_dir, const char *seq_dir, const float *pos, uint32_t frames, uint32_t V)
{
    const char *base = strrchr(seq_dir, '/');
    base = base && base[1] ? base + 1 : seq_dir;
    char path[2048];
    int n = snprintf(path, sizeof path, "%s/%s.npy", out_dir, base);
    const uint64_t shape[3] = {frames, V, 3};
    if (!pos || n <= 0 || (size_t)n >= sizeof path || !bench_mkdirs(out_dir) ||
        !weft_npy_write_file(path, "<f4", shape, 3, pos, (size_t)frames * V * 3 * sizeof(float))) {
        fprintf(stderr, "weft eval: cannot write the rollout to %s\n", path);
        return false;
    }
    return true;
}

/* For each of n points of `from` (xyz), the index of the nearest of the m points of `to`.
 * Brute force, once per sequence: 1k x 4k vertices is a few milliseconds. */
static void nearest_vertices(const float *from, uint32_t n, const float *to, uint32_t m, uint32_t *out)
{
    for (uint32_t i = 0; i < n; ++i) {
        double best = INFINITY;
        out[i] = 0;
        for (uint32_t j = 0; j < m; ++j) {
            double dd = 0.0;
            for (int k = 0; k < 3; ++k) {
                const double e = (double)from[3 * (size_t)i + k] - to[3 * (size_t)j + k];
                dd += e * e;
            }
            if (dd < best) {
                best = dd;
                out[i] = j;
            }
        }
    }
}

/* The sequence's pin mask of one frame carried onto the simulated mesh: a simulated vertex is
 * pinned when its nearest scored vertex is, and so is the simulated vertex nearest to each
 * pinned scored vertex, so a grasp smaller than the coarse mesh's spacing still holds one. */
static void sim_pins_at(const float *mask, uint32_t V, const uint32_t *near_scored, const uint32_t *near_sim,
                        uint32_t SV, uint8_t *sim_mask)
{
    for (uint32_t i = 0; i < SV; ++i) {
        sim_mask[i] = mask[near_scored[i]] != 0.0f;
    }
    for (uint32_t j = 0; j < V; ++j) {
        if (mask[j] != 0.0f) {
            sim_mask[near_sim[j]] = 1;
        }
    }
}

static int eval_sequence(weft_context *ctx, const weft_model *model, const eval_opts *o, const char *dir,
                         eval_acc *total, bool print)
{
    seq_data s;
    if (seq_load(dir, &s) != WEFT_OK) {
        return 1;
    }
    const size_t nv = (size_t)s.V * 3, nc = (size_t)s.Vc * 3;
    /* --sim-mesh: the garment is simulated on another mesh of the same garment (e.g. its 1k
     * version for this 4k sequence) and mapped onto this sequence's mesh, which is what is scored:
     * `down` samples the ground truth onto the simulated mesh to start it, `up` maps every step
     * back. Pins reach the simulated mesh through nearest vertices (see sim_pins_at). */
    float *sim_rest = NULL, *sim_x1 = NULL, *sim_x0 = NULL, *mapped = NULL, *sim_gt = NULL;
    uint32_t *sim_faces = NULL, *near_scored = NULL, *near_sim = NULL;
    uint32_t SV = s.V, SF = s.F;
    weft_mesh_map *down = NULL, *up = NULL;
    if (o->sim_mesh) {
        uint64_t sr[3] = {0}, sf[3] = {0};
        weft_result lr = load_npy(o->sim_mesh, "rest_pos", 2, false, (void **)&sim_rest, sr, false);
        if (lr == WEFT_OK) {
            lr = load_npy(o->sim_mesh, "faces", 2, true, (void **)&sim_faces, sf, false);
        }
        SV = (uint32_t)sr[0];
        SF = (uint32_t)sf[0];
        weft_mesh_map_def md = weft_default_mesh_map_def();
        md.from_rest_positions = s.rest;
        md.from_vertex_count = s.V;
        md.from_triangles = s.faces;
        md.from_triangle_count = s.F;
        md.to_rest_positions = sim_rest;
        md.to_vertex_count = SV;
        if (lr == WEFT_OK) {
            lr = weft_mesh_map_create(ctx, &md, &down);
        }
        weft_mesh_map_def mu = weft_default_mesh_map_def();
        mu.from_rest_positions = sim_rest;
        mu.from_vertex_count = SV;
        mu.from_triangles = sim_faces;
        mu.from_triangle_count = SF;
        mu.to_rest_positions = s.rest;
        mu.to_vertex_count = s.V;
        if (lr == WEFT_OK) {
            lr = weft_mesh_map_create(ctx, &mu, &up);
        }
        sim_x1 = malloc((size_t)SV * 3 * sizeof(float));
        sim_x0 = malloc((size_t)SV * 3 * sizeof(float));
        sim_gt = malloc((size_t)SV * 3 * sizeof(float));
        mapped = malloc(nv * sizeof(float));
        if (lr == WEFT_OK && (!sim_x1 || !sim_x0 || !sim_gt || !mapped)) {
            lr = WEFT_ERROR_OUT_OF_MEMORY;
        }
        if (lr == WEFT_OK && s.pinned) { /* the nearest-vertex tables only carry pins */
            near_scored = malloc((size_t)SV * sizeof(uint32_t));
            near_sim = malloc((size_t)s.V * sizeof(uint32_t));
            lr = near_scored && near_sim ? WEFT_OK : WEFT_ERROR_OUT_OF_MEMORY;
        }
        if (lr == WEFT_OK && s.pinned) {
            nearest_vertices(sim_rest, SV, s.rest, s.V, near_scored);
            nearest_vertices(s.rest, s.V, sim_rest, SV, near_sim);
        }
        if (lr == WEFT_OK && (lr = weft_mesh_map_apply(down, s.pos + nv, sim_x1)) == WEFT_OK) {
            lr = weft_mesh_map_apply(down, s.pos, sim_x0);
        }
        if (lr != WEFT_OK) {
            fprintf(stderr, "weft eval: --sim-mesh %s for %s: %s: %s\n", o->sim_mesh, dir, weft_result_string(lr),
                    weft_last_error());
            weft_mesh_map_destroy(down);
            weft_mesh_map_destroy(up);
            free(sim_rest), free(sim_faces), free(sim_x1), free(sim_x0), free(sim_gt), free(mapped);
            free(near_scored), free(near_sim);
            seq_free(&s);
            return 1;
        }
    }
    weft_garment_def d = weft_default_garment_def();
    d.method = o->method;
    d.model = model;
    d.precision = o->precision;
    d.substeps = o->substeps;
    d.ccd.enabled = o->ccd;
    d.ccd.iterations = o->ccd_iterations;
    d.collider_crop_margin = o->crop_margin;
    d.collider_crop = o->crop;
    d.max_collider_tokens = o->max_collider_tokens;
    d.collider_cap = o->collider_cap;
    d.rest_positions = up ? sim_rest : s.rest;
    d.vertex_count = SV;
    d.triangles = up ? sim_faces : s.faces;
    d.triangle_count = SF;
    if (s.cpos) {
        d.collider_rest_positions = s.cpos + nc; /* the collider at frame 1, where the rollout starts */
        d.collider_vertex_count = s.Vc;
        d.collider_triangles = s.cfaces;
        d.collider_triangle_count = s.Fc;
    }
    d.initial_positions = up ? sim_x1 : s.pos + nv;
    /* Tethers: the radius everywhere, 0 on vertices pinned at the start (a skirt's waistband), so
     * a method without pins keeps the scenario's attachment; on a --sim-mesh, the vertices the
     * sequence's pins reach there. */
    float *radii = NULL;
    d.tethers.distance = o->tether; /* a bad radius, or tethers without a collider, fail in the library */
    d.strain.limit = o->strain_limit;
    d.strain.contact = o->strain_contact;
    d.collision.push = o->push;
    d.collision.push_depth = o->push_depth;
    /* a worn garment (read once: its kind for the recipe, its off-body distance for the wear measures) */
    float off_distance = 0.10f;
    weft_cloth_kind kind = WEFT_CLOTH_TSHIRT;
    const bool worn = s.cpos && worn_garment(dir, &off_distance, &kind);
#if !WEFT_HAVE_RENDER
    (void)worn; /* the recipe and the wear measures come with the samples' build */
#endif
#if WEFT_RENDER_HAVE_SAMPLE
    if (o->recipe_worn && worn) {
        weft_sample_worn_recipe(&d, kind, o->method); /* as the render sample and bench mocap wear it */
    }
#endif
    const float tether = d.tethers.distance;
    uint8_t *sim_pinned = up && s.pinned ? calloc(SV, 1) : NULL;
    if (tether > 0.0f && s.cpos) {
        radii = malloc((size_t)SV * sizeof(float));
        if (sim_pinned) {
            sim_pins_at(s.pinned + (size_t)1 * s.V, s.V, near_scored, near_sim, SV, sim_pinned);
        }
        for (uint32_t i = 0; radii && i < SV; ++i) {
            const bool pinned_at_start =
                up ? sim_pinned && sim_pinned[i] : s.pinned && s.pinned[(size_t)1 * s.V + i] != 0.0f;
            radii[i] = pinned_at_start ? 0.0f : tether;
        }
        d.tethers.distances = radii;
    }
    weft_garment *g = NULL;
    weft_result r = weft_garment_create(ctx, &d, &g);
    free(radii);
    if (r == WEFT_OK) {
        r = up ? weft_garment_set_state(g, sim_x1, sim_x0) : weft_garment_set_state(g, s.pos + nv, s.pos);
    }
    if (r != WEFT_OK) {
        fprintf(stderr, "weft eval: %s: %s: %s\n", dir, weft_result_string(r), weft_last_error());
        weft_garment_destroy(g);
        weft_mesh_map_destroy(down);
        weft_mesh_map_destroy(up);
        free(sim_rest), free(sim_faces), free(sim_x1), free(sim_x0), free(sim_gt), free(mapped);
        free(near_scored), free(near_sim), free(sim_pinned);
        seq_free(&s);
        return 1;
    }
    weft_ccd_world *world = NULL;
    weft_ccd_world_def wd = weft_default_ccd_world_def();
    wd.cloth_triangles = s.faces;
    wd.cloth_triangle_count = s.F;
    wd.cloth_vertex_count = s.V;
    wd.cloth_layout_positions = s.rest;
    if (s.cpos) {
        wd.collider_triangles = s.cfaces;
        wd.collider_triangle_count = s.Fc;
        wd.collider_vertex_count = s.Vc;
        wd.collider_layout_positions = s.cpos;
    }
    bool metrics = weft_ccd_world_create(ctx, &wd, &world) == WEFT_OK;
    if (!metrics) {
        fprintf(stderr, "weft eval: %s: collision metrics unavailable: %s\n", dir, weft_last_error());
    }
#if WEFT_HAVE_RENDER
    /* wear measures for a worn garment, against the garment the skin carries */
    weft_wear *wear = NULL;
    float *skinned = NULL;
    if (!up && worn) {
        skinned = malloc(nv * sizeof(float));
        if (!skinned || weft_wear_create(s.cfaces, s.Fc, s.Vc, s.V, &wear) != WEFT_OK ||
            weft_garment_skinned_positions(g, skinned) != WEFT_OK) {
            fprintf(stderr, "weft eval: %s: wear measures unavailable: %s\n", dir, weft_last_error());
            weft_wear_destroy(wear);
            wear = NULL;
        }
    }
#endif
    uint32_t ne = 0;
    uint32_t *edges = edges_of(&s, &ne);
    float *prev = malloc(nv * sizeof(float));
    /* Gripper attachments: pinned vertices follow their ground-truth positions (the scenario's
     * boundary condition). By default only XPBD gets them, inside its solve, and the learned and
     * LBS methods see only the gripper (the protocol of the documented tables); --pins all gives
     * every method the pins (the library sets them after a learned or LBS step). On a --sim-mesh
     * they are set on the simulated mesh, at the reference sampled there through `down`. */
    const bool use_pins = s.pinned && (!up || sim_pinned) && (o->pins_all || o->method == WEFT_METHOD_XPBD || o->method == WEFT_METHOD_XPBD_FAST);
    uint32_t *pin_idx = use_pins ? malloc((size_t)SV * sizeof(uint32_t)) : NULL;
    float *pin_pos = use_pins ? malloc((size_t)SV * 3 * sizeof(float)) : NULL;
    bool pins = pin_idx && pin_pos;
    /* The scored positions: the garment's own, or its map onto this sequence's mesh. */
    const float *cur = weft_garment_positions(g);
    if (up && (r = weft_mesh_map_apply(up, cur, mapped)) == WEFT_OK) {
        cur = mapped;
    }
    eval_acc a = {0};
    a.metrics_ok = metrics;
    uint32_t last = s.T - 1;
    if (o->max_frames && o->max_frames + 1 < last) {
        last = o->max_frames + 1;
    }
    /* --write-pos: the two reference frames the rollout starts from, then every step's positions. */
    float *rollout = o->write_pos ? malloc((size_t)(last + 1) * nv * sizeof(float)) : NULL;
    if (rollout) {
        memcpy(rollout, s.pos, 2 * nv * sizeof(float));
    }
    for (uint32_t t = 1; t < last && edges && prev; ++t) {
        if (o->time_limit_ms > 0 && a.ms_sum > o->time_limit_ms) {
            a.time_limited = true;
            break;
        }
        memcpy(prev, cur, nv * sizeof(float));
        if (s.cpos && (r = weft_garment_set_collider(g, s.cpos + (size_t)(t + 1) * nc)) != WEFT_OK) {
            break;
        }
        if (pins) {
            const float *pm = s.pinned + (size_t)(t + 1) * s.V;
            const float *gtp = s.pos + (size_t)(t + 1) * nv;
            uint32_t np = 0;
            if (up) {
                sim_pins_at(pm, s.V, near_scored, near_sim, SV, sim_pinned);
                if ((r = weft_mesh_map_apply(down, gtp, sim_gt)) != WEFT_OK) {
                    break;
                }
                gtp = sim_gt;
            }
            for (uint32_t i = 0; i < SV; ++i) {
                if (up ? sim_pinned[i] != 0 : pm[i] != 0.0f) {
                    pin_idx[np] = i;
                    memcpy(pin_pos + 3 * (size_t)np, gtp + 3 * (size_t)i, 3 * sizeof(float));
                    np++;
                }
            }
            if ((r = weft_garment_set_pins(g, pin_idx, pin_pos, np)) != WEFT_OK) {
                fprintf(stderr, "weft eval: %s: frame %u: pins: %s\n", dir, t + 1, weft_last_error());
                break;
            }
        }
        double t0 = now_ms();
        r = weft_garment_step(g);
        /* A garment simulated on a coarser mesh is drawn through its map: part of the frame's cost. */
        const weft_result mr = r == WEFT_OK && up ? weft_mesh_map_apply(up, weft_garment_positions(g), mapped) : WEFT_OK;
        const double step_ms = now_ms() - t0;
        a.ms_sum += step_ms;
        a.tokens_sum += weft_garment_stats(g).collider_tokens;
        a.ccd_passes_sum += weft_garment_stats(g).ccd_iterations;
        a.pushed_sum += weft_garment_stats(g).pushed_vertices;
        a.push_far_sum += weft_garment_stats(g).push_from_far_side;
        a.let_out_sum += weft_garment_stats(g).ccd_let_out;
        if (r == WEFT_ERROR_NOT_FINITE) {
            a.nan = true;
            break;
        }
        if (r != WEFT_OK) {
            fprintf(stderr, "weft eval: %s: frame %u: %s: %s\n", dir, t + 1, weft_result_string(r), weft_last_error());
            break;
        }
        if ((r = mr) != WEFT_OK) {
            fprintf(stderr, "weft eval: %s: frame %u: mapping onto the scored mesh: %s\n", dir, t + 1, weft_last_error());
            break;
        }
        const float *x = up ? mapped : weft_garment_positions(g);
        cur = x;
        if (rollout) {
            memcpy(rollout + (size_t)(t + 1) * nv, x, nv * sizeof(float));
        }
        const float *gt = s.pos + (size_t)(t + 1) * nv;
        for (uint32_t i = 0; i < s.V; ++i) {
            double dx = (double)x[3 * i] - gt[3 * i], dy = (double)x[3 * i + 1] - gt[3 * i + 1],
                   dz = (double)x[3 * i + 2] - gt[3 * i + 2];
            a.err_sum += sqrt(dx * dx + dy * dy + dz * dz);
        }
        a.vert_frames += s.V;
        push_frame_ms(&a, step_ms);
        push_frame_ms(total, step_ms);
        a.frames++;
#if WEFT_HAVE_RENDER
        if (wear) {
            weft_wear_frame wf;
            if (weft_garment_skinned_positions(g, skinned) != WEFT_OK ||
                weft_wear_measure(wear, s.cpos + (size_t)(t + 1) * nc, x, skinned, off_distance, &wf) != WEFT_OK) {
                fprintf(stderr, "weft eval: %s: frame %u: wear: %s\n", dir, t + 1, weft_last_error());
                r = WEFT_ERROR_INVALID_ARGUMENT;
                break;
            }
            weft_wear_summary_add(&a.wear, &wf);
        }
#endif
        uint32_t over = 0;
        a.max_strain = fmax(a.max_strain, max_strain(x, s.rest, edges, ne, &over));
        a.overstretched_pct = fmax(a.overstretched_pct, ne ? 100.0 * over / ne : 0.0);
        a.gt_max_strain = fmax(a.gt_max_strain, max_strain(gt, s.rest, edges, ne, NULL));
        if (metrics) {
            weft_ccd_metrics m;
            const float *c0 = s.cpos ? s.cpos + (size_t)t * nc : NULL;
            const float *c1 = s.cpos ? s.cpos + (size_t)(t + 1) * nc : NULL;
            if (weft_ccd_compute_metrics(world, prev, x, c0, c1, &m) == WEFT_OK) {
                a.coll_sum += m.collision_rate;
                a.self_sum += m.self_collision_rate;
                a.metric_frames++;
            }
        }
    }
    /* A rollout that went non-finite or scored no frame failed: it has no MVE, and eval exits 1. */
    int rc = r == WEFT_OK && !a.nan && a.frames > 0 ? 0 : 1;
    if (a.nan) {
        fprintf(stderr, "weft eval: %s: the rollout went non-finite at frame %u; it is not scored\n", dir, a.frames + 1);
    } else if (r == WEFT_OK && a.frames == 0) {
        fprintf(stderr, "weft eval: %s: no frame was scored\n", dir);
    }
    if (o->write_pos && !write_rollout(o->write_pos, dir, rollout, a.frames + 2, s.V)) {
        rc = 1;
    }
    free(rollout);
    char p50[32], pmax[32];
    ms_percentile(&a, 50.0, p50, sizeof p50);
    ms_percentile(&a, 100.0, pmax, sizeof pmax);
    if (print && rc != 0) {
        printf("%-40s frames %4u  FAILED%s\n", dir, a.frames, a.nan ? " (NaN)" : "");
    } else if (print) {
        printf("%-40s frames %4u  MVE %8.3f cm  coll %6.2f%%  self %6.2f%%  %8.3f ms/frame (p50 %s, max %s)  strain "
               "%.3f  tokens %.0f%s",
               dir, a.frames, a.vert_frames > 0 ? a.err_sum / a.vert_frames * 100.0 : 0.0,
               a.metric_frames ? a.coll_sum / a.metric_frames : 0.0,
               a.metric_frames ? a.self_sum / a.metric_frames : 0.0, a.frames ? a.ms_sum / a.frames : 0.0, p50, pmax,
               a.max_strain, a.frames ? a.tokens_sum / a.frames : 0.0, a.nan ? "  NaN" : "");
#if WEFT_HAVE_RENDER
        if (wear) {
            printf("  garment %s (off_body max %.1f%%), inside %.1f%% mean %.1f%% max, body overlap %.1f%%",
                   a.wear.frames_off ? "LOST" : "kept", 100.0 * a.wear.off_body_max, 100.0 * a.wear.inside_mean,
                   100.0 * a.wear.inside_max, 100.0 * a.wear.overlap_mean);
        }
#endif
        printf("\n");
    }
#if WEFT_HAVE_RENDER
    if (wear && a.wear.frames > 0) {
        /* the total's wear: frame-weighted means, maxima, lost sequences */
        weft_wear_summary *w = &total->wear;
        const double n0 = w->frames, n1 = a.wear.frames;
        w->inside_mean = (w->inside_mean * n0 + a.wear.inside_mean * n1) / (n0 + n1);
        w->overlap_mean = (w->overlap_mean * n0 + a.wear.overlap_mean * n1) / (n0 + n1);
        w->inside_max = fmax(w->inside_max, a.wear.inside_max);
        w->overlap_max = fmax(w->overlap_max, a.wear.overlap_max);
        w->inside_clear_mean = (w->inside_clear_mean * n0 + a.wear.inside_clear_mean * n1) / (n0 + n1);
        w->inside_clear_max = fmax(w->inside_clear_max, a.wear.inside_clear_max);
        w->off_body_max = fmax(w->off_body_max, a.wear.off_body_max);
        w->frames_off += a.wear.frames_off;
        w->frames += a.wear.frames;
        total->worn_sequences++;
        total->lost_sequences += a.wear.frames_off > 0;
    }
    weft_wear_destroy(wear);
    free(skinned);
#endif
    free(a.frame_ms);
    total->err_sum += a.err_sum;
    total->vert_frames += a.vert_frames;
    total->coll_sum += a.coll_sum;
    total->self_sum += a.self_sum;
    total->metric_frames += a.metric_frames;
    total->ms_sum += a.ms_sum;
    total->tokens_sum += a.tokens_sum;
    total->ccd_passes_sum += a.ccd_passes_sum;
    total->pushed_sum += a.pushed_sum;
    total->push_far_sum += a.push_far_sum;
    total->let_out_sum += a.let_out_sum;
    total->frames += a.frames;
    total->nan = total->nan || a.nan;
    total->max_strain = fmax(total->max_strain, a.max_strain);
    total->gt_max_strain = fmax(total->gt_max_strain, a.gt_max_strain);
    total->overstretched_pct = fmax(total->overstretched_pct, a.overstretched_pct);
    total->time_limited = total->time_limited || a.time_limited;
    total->metrics_ok = total->metrics_ok && metrics;
    total->sequences++;
    free(pin_idx);
    free(pin_pos);
    free(prev);
    free(edges);
    weft_ccd_world_destroy(world);
    weft_garment_destroy(g);
    weft_mesh_map_destroy(down);
    weft_mesh_map_destroy(up);
    free(sim_rest), free(sim_faces), free(sim_x1), free(sim_x0), free(sim_gt), free(mapped);
    free(near_scored), free(near_sim), free(sim_pinned);
    seq_free(&s);
    return rc;
}

static bool is_file(const char *dir, const char *name)
{
    char p[1024];
    struct stat st;
    return path_join(p, sizeof p, dir, name) && stat(p, &st) == 0 && S_ISREG(st.st_mode);
}


static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

enum {
    OPT_SEQ = 1, OPT_MODEL, OPT_METHOD, OPT_PRECISION, OPT_CCD, OPT_CCD_ITERATIONS, OPT_SPLIT, OPT_FRAMES, OPT_JSON,
    OPT_CROP_CM, OPT_CROP, OPT_MAX_COLLIDER_TOKENS, OPT_TOKEN_CAP, OPT_TETHER_CM, OPT_STRAIN_LIMIT, OPT_STRAIN_CONTACT_CM,
    OPT_SIM_MESH, OPT_TIME_LIMIT, OPT_PUSH_CM, OPT_PUSH_DEPTH_CM, OPT_WRITE_POS, OPT_PINS, OPT_RECIPE,
};

static const cli_option k_options[] = {
    {"seq", "DIR", OPT_SEQ, "one sequence folder (meta.json + .npy) or a folder of them (required)"},
    {"model", "M", OPT_MODEL, "the learned model (required for method model)"},
    {"method", "model|lbs|xpbd:S|xpbd-fast:S", OPT_METHOD,
     "the method (default model): xpbd:S the reference solver at S substeps\n"
     "(1..1000, default 10); xpbd-fast:S the same material with a game's\n"
     "collision projection instead of its bounds"},
    {"precision", "fp32|fp16|int8", OPT_PRECISION, "the model's precision (default fp32)"},
    {"ccd", "on|off", OPT_CCD, "the CCD post-process (default on)"},
    {"ccd-iterations", "N", OPT_CCD_ITERATIONS, "CCD back-off passes before its fallback (1..64, default below)"},
    {"split", "train|val|test", OPT_SPLIT, "in a folder of sequences, only those of this split"},
    {"frames", "N", OPT_FRAMES, "score at most N frames per sequence (1..100000000)"},
    {"json", NULL, OPT_JSON, "print the totals as one JSON object (no per-sequence lines)"},
    {"crop-cm", "X", OPT_CROP_CM, "the model's collider crop margin, 0..10000 cm (0: the model's own)"},
    {"crop", "box|cells", OPT_CROP,
     "the model's collider crop: box (default, as the model was trained) or\n"
     "cells (finer: within the margin of the occupied cells of a coarse grid)"},
    {"max-collider-tokens", "N", OPT_MAX_COLLIDER_TOKENS, "keep at most N collider triangles (0..4294967295, 0: all)"},
    {"token-cap", "nearest|sample", OPT_TOKEN_CAP,
     "how --max-collider-tokens chooses: nearest (default: the triangles nearest\n"
     "the garment) or sample (an even sample of the crop, weighted in the\n"
     "attention; weft_collider_cap)"},
    {"tether-cm", "X", OPT_TETHER_CM,
     "tethers to the skinned garment, radius X cm, 0..1000 (0 on vertices\n"
     "pinned at the start)"},
    {"strain-limit", "PCT", OPT_STRAIN_LIMIT,
     "shorten edges stretched over PCT %, 0..1000 (0: off), after each step\n"
     "(and in CCD)"},
    {"strain-contact-cm", "X", OPT_STRAIN_CONTACT_CM,
     "contact-aware limit, 0..100: vertices within X cm of the collider stay\n"
     "put while it shortens edges (weft_garment_def.strain.contact)"},
    {"push-cm", "X", OPT_PUSH_CM,
     "push cloth inside the collider (up to --push-depth-cm) or closer than X\n"
     "cm, 0..10, to X cm in front of it, before CCD\n"
     "(weft_garment_def.collision.push)"},
    {"push-depth-cm", "X", OPT_PUSH_DEPTH_CM,
     "how deep inside the collider --push-cm still pushes cloth out, 0..50 cm\n"
     "(default below; weft_garment_def.collision.push_depth)"},
    {"sim-mesh", "DIR", OPT_SIM_MESH,
     "simulate on DIR's rest_pos.npy + faces.npy (the same garment at another\n"
     "resolution) and score its map onto the sequence's mesh (ms/frame\n"
     "includes the map); a simulated vertex is pinned where its nearest scored\n"
     "vertex is, and so is the nearest one to each pinned scored vertex, at\n"
     "the reference sampled there"},
    {"time-limit", "S", OPT_TIME_LIMIT,
     "stop each rollout once its steps took S seconds, 0.001..1e6 (JSON:\n"
     "time_limited, frames)"},
    {"pins", "xpbd|all", OPT_PINS,
     "the sequence's pins (gripper grasps) for the XPBD methods only (default,\n"
     "the documented protocol) or for every method (set after a learned or LBS\n"
     "step)"},
    {"recipe", "none|worn", OPT_RECIPE,
     "worn: each worn garment (scenario garment) as a game wears it, the\n"
     "worn-garment recipe of docs/WEAR.md for its kind and the method (max\n"
     "distance, push, floor, the model's strain limit and sampled tokens);\n"
     "replaces the options it sets (default none)"},
    {"write-pos", "DIR", OPT_WRITE_POS,
     "write each rollout to DIR/<sequence>.npy, [frames + 2, N, 3] float32:\n"
     "the two reference frames it starts from, then every step (on the scored\n"
     "mesh)"},
    {0},
};

static void notes(FILE *out)
{
    const weft_garment_def d = weft_default_garment_def();
    fprintf(out, "Defaults: --ccd-iterations %u, --push-depth-cm %g.\n", d.ccd.iterations,
            (double)d.collision.push_depth * 100.0);
}

static const cli_command k_command = {
    .tool = "weft eval",
    .synopsis = "weft eval --seq DIR [--model M] [--method model|lbs|xpbd:S|xpbd-fast:S]\n"
                "          [--precision fp32|fp16|int8] [--ccd on|off] [--ccd-iterations N]\n"
                "          [--split train|val|test] [--frames N] [--json] [--crop-cm X] [--crop box|cells]\n"
                "          [--max-collider-tokens N] [--token-cap nearest|sample] [--tether-cm X]\n"
                "          [--strain-limit PCT]\n"
                "          [--strain-contact-cm X] [--sim-mesh DIR] [--time-limit S] [--push-cm X]\n"
                "          [--push-depth-cm X] [--write-pos DIR] [--pins xpbd|all] [--recipe none|worn]",
    .about = "Scores a method's rollout against simgen sequences (MVE, collisions, timing).",
    .options = k_options,
    .notes = notes,
};

static const char k_tool[] = "weft eval";

/* A whole-string number of hundredths (cm or %) in [0, hi], as a fraction of one: metres or a
 * ratio. */
static bool parse_hundredths(const char *option, const char *v, float hi, float *out)
{
    float f = 0.0f;
    if (!cli_float(k_tool, option, v, 0.0f, hi, &f)) {
        return false;
    }
    *out = f / 100.0f;
    return true;
}

int weft_cmd_eval(int argc, char **argv)
{
    eval_opts o = {.method = WEFT_METHOD_MODEL, .substeps = 10, .precision = WEFT_PRECISION_FP32, .ccd = true,
                   .ccd_iterations = weft_default_garment_def().ccd.iterations,
                   .push_depth = weft_default_garment_def().collision.push_depth};
    cli_parser parser;
    cli_start(&parser, &k_command, argc, argv);
    const char *v;
    char recipe_set[32] = ""; /* the first option given that --recipe worn also sets */
    for (int id; (id = cli_next(&parser, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        if (!recipe_set[0] && (id == OPT_TETHER_CM || id == OPT_STRAIN_LIMIT || id == OPT_PUSH_CM ||
                            id == OPT_PUSH_DEPTH_CM || id == OPT_MAX_COLLIDER_TOKENS || id == OPT_TOKEN_CAP)) {
            snprintf(recipe_set, sizeof recipe_set, "%s", a);
        }
        switch (id) {
        case CLI_STOP:
            return parser.exit;
        case OPT_JSON:
            o.json = true;
            break;
        case OPT_MODEL:
            o.model_path = v;
            break;
        case OPT_SEQ:
            o.seq = v;
            break;
        case OPT_SPLIT:
            o.split = v;
            break;
        case OPT_FRAMES:
            if (!cli_u32(k_tool, a, v, 1, 100000000, &o.max_frames)) {
                return 2;
            }
            break;
        case OPT_METHOD:
            if (strcmp(v, "model") == 0) {
                o.method = WEFT_METHOD_MODEL;
            } else if (strcmp(v, "lbs") == 0) {
                o.method = WEFT_METHOD_LBS;
            } else if (strncmp(v, "xpbd", 4) == 0) {
                /* xpbd[:S], or xpbd-fast[:S] (game-style collision projection) */
                const bool fast = strncmp(v, "xpbd-fast", 9) == 0;
                const size_t at = fast ? 9 : 4;
                o.method = fast ? WEFT_METHOD_XPBD_FAST : WEFT_METHOD_XPBD;
                if (v[at] == ':') {
                    if (!cli_u32(k_tool, "--method's substep count", v + at + 1, 1, 1000, &o.substeps)) {
                        return 2;
                    }
                } else if (v[at] != '\0') {
                    fprintf(stderr, "weft eval: unknown method '%s'\n", v);
                    return 2;
                }
            } else {
                fprintf(stderr, "weft eval: unknown method '%s'\n", v);
                return 2;
            }
            break;
        case OPT_PRECISION:
            if (strcmp(v, "fp32") == 0) {
                o.precision = WEFT_PRECISION_FP32;
            } else if (strcmp(v, "fp16") == 0) {
                o.precision = WEFT_PRECISION_FP16;
            } else if (strcmp(v, "int8") == 0) {
                o.precision = WEFT_PRECISION_INT8;
            } else {
                fprintf(stderr, "weft eval: unknown precision '%s'\n", v);
                return 2;
            }
            break;
        case OPT_CROP_CM:
            /* model collider crop margin in cm (0: the model's own); the library validates it */
            if (!parse_hundredths(a, v, 10000.0f, &o.crop_margin)) {
                return 2;
            }
            break;
        case OPT_TIME_LIMIT: {
            double sec = 0.0;
            if (!cli_double(k_tool, a, v, 0.001, 1e6, &sec)) {
                return 2;
            }
            o.time_limit_ms = sec * 1e3;
            break;
        }
        case OPT_RECIPE:
            if (!cli_either(k_tool, a, v, "none", "worn", &o.recipe_worn)) {
                return 2;
            }
            break;
        case OPT_PINS:
            if (!cli_either(k_tool, a, v, "xpbd", "all", &o.pins_all)) {
                return 2;
            }
            break;
        case OPT_WRITE_POS:
            o.write_pos = v;
            break;
        case OPT_SIM_MESH:
            o.sim_mesh = v; /* rest_pos.npy + faces.npy of the same garment at another resolution */
            break;
        case OPT_TETHER_CM:
            /* tethers to the skinned garment, radius in cm (0: off); the library validates it */
            if (!parse_hundredths(a, v, 1000.0f, &o.tether)) {
                return 2;
            }
            break;
        case OPT_STRAIN_LIMIT:
            /* percent over rest length (0: off); the library validates it */
            if (!parse_hundredths(a, v, 1000.0f, &o.strain_limit)) {
                return 2;
            }
            break;
        case OPT_STRAIN_CONTACT_CM:
            if (!parse_hundredths(a, v, 100.0f, &o.strain_contact)) {
                return 2;
            }
            break;
        case OPT_PUSH_CM:
        case OPT_PUSH_DEPTH_CM: {
            const bool push = id == OPT_PUSH_CM;
            if (!parse_hundredths(a, v, push ? 10.0f : 50.0f, push ? &o.push : &o.push_depth)) {
                return 2;
            }
            break;
        }
        case OPT_CROP: {
            bool cells = false;
            if (!cli_either(k_tool, a, v, "box", "cells", &cells)) {
                return 2;
            }
            o.crop = cells ? WEFT_COLLIDER_CROP_CELLS : WEFT_COLLIDER_CROP_BOX;
            break;
        }
        case OPT_MAX_COLLIDER_TOKENS:
            if (!cli_u32(k_tool, a, v, 0, UINT32_MAX, &o.max_collider_tokens)) {
                return 2;
            }
            break;
        case OPT_TOKEN_CAP: {
            bool sample = false;
            if (!cli_either(k_tool, a, v, "nearest", "sample", &sample)) {
                return 2;
            }
            o.collider_cap = sample ? WEFT_COLLIDER_CAP_SAMPLE : WEFT_COLLIDER_CAP_NEAREST;
            break;
        }
        case OPT_CCD:
            if (!cli_either(k_tool, a, v, "off", "on", &o.ccd)) {
                return 2;
            }
            break;
        case OPT_CCD_ITERATIONS:
            if (!cli_u32(k_tool, a, v, 1, 64, &o.ccd_iterations)) {
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
    if (!o.seq || (o.method == WEFT_METHOD_MODEL && !o.model_path)) {
        return cli_fail(&k_command, "--seq is required, and --model for method 'model'");
    }
    if (o.recipe_worn && recipe_set[0]) {
        fprintf(stderr, "weft eval: --recipe worn sets %s itself; pass one or the other\n", recipe_set);
        return 2;
    }
#if !WEFT_RENDER_HAVE_SAMPLE
    if (o.recipe_worn) {
        fprintf(stderr, "weft eval: --recipe worn needs the samples' build (WEFT_BUILD_SAMPLES)\n");
        return 2;
    }
#endif
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_result r = weft_context_create(&cd, &ctx);
    if (r != WEFT_OK) {
        fprintf(stderr, "weft eval: %s\n", weft_last_error());
        return 1;
    }
    weft_model *model = NULL;
    if (o.model_path && (r = weft_model_load_file_as(ctx, o.model_path, "clothtransformer", &model)) != WEFT_OK) {
        fprintf(stderr, "weft eval: %s: %s: %s\n", o.model_path, weft_result_string(r), weft_last_error());
        weft_context_destroy(ctx);
        return 1;
    }
    eval_acc total = {.metrics_ok = true};
    int rc = 0;
    if (is_file(o.seq, "meta.json") && is_file(o.seq, "cloth_pos.npy")) {
        rc = eval_sequence(ctx, model, &o, o.seq, &total, !o.json);
    } else {
        DIR *dh = opendir(o.seq);
        if (!dh) {
            fprintf(stderr, "weft eval: cannot open %s\n", o.seq);
            rc = 1;
        } else {
            char **names = NULL;
            size_t count = 0, cap = 0;
            struct dirent *de;
            while ((de = readdir(dh)) != NULL) {
                if (de->d_name[0] == '.') {
                    continue;
                }
                if (count == cap) {
                    cap = cap ? 2 * cap : 64;
                    char **nn = realloc(names, cap * sizeof *names);
                    if (!nn) {
                        break;
                    }
                    names = nn;
                }
                names[count++] = strdup(de->d_name);
            }
            closedir(dh);
            if (count) {
                qsort(names, count, sizeof *names, cmp_str);
            }
            for (size_t i = 0; i < count; ++i) {
                char path[1024];
                if (path_join(path, sizeof path, o.seq, names[i]) && is_file(path, "meta.json") && is_file(path, "cloth_pos.npy") &&
                    (!o.split || strcmp(weft_sim_sequence_split(path), o.split) == 0)) {
                    rc |= eval_sequence(ctx, model, &o, path, &total, !o.json);
                }
                free(names[i]);
            }
            free(names);
        }
    }
    if (total.sequences == 0 && rc == 0) {
        fprintf(stderr, "weft eval: no sequences (meta.json + cloth_pos.npy) under %s\n", o.seq);
        rc = 1;
    }
    double mve = total.vert_frames > 0 ? total.err_sum / total.vert_frames * 100.0 : 0.0;
    double coll = total.metric_frames ? total.coll_sum / total.metric_frames : 0.0;
    double self = total.metric_frames ? total.self_sum / total.metric_frames : 0.0;
    double ms = total.frames ? total.ms_sum / total.frames : 0.0;
    double tokens = total.frames ? total.tokens_sum / total.frames : 0.0;
    double passes = total.frames ? total.ccd_passes_sum / total.frames : 0.0;
    double pushed = total.frames ? total.pushed_sum / total.frames : 0.0;
    double push_far = total.frames ? total.push_far_sum / total.frames : 0.0;
    double let_out = total.frames ? total.let_out_sum / total.frames : 0.0;
    /* Never a score for a failed run: any sequence that failed, went non-finite or scored nothing
     * leaves the error metrics null and the exit status 1. */
    const bool failed = rc != 0 || total.nan || total.frames == 0;
    rc = failed ? 1 : 0;
    char ms_p50[32], ms_p99[32], ms_max[32];
    ms_percentile(&total, 50.0, ms_p50, sizeof ms_p50);
    ms_percentile(&total, 99.0, ms_p99, sizeof ms_p99);
    ms_percentile(&total, 100.0, ms_max, sizeof ms_max);
    char wear_json[512] = "null", wear_text[256] = "";
#if WEFT_HAVE_RENDER
    if (total.worn_sequences > 0) {
        const weft_wear_summary *w = &total.wear;
        snprintf(wear_json, sizeof wear_json,
                 "{\"sequences\": %u, \"garments_lost\": %u, \"frames_off_body\": %u, \"off_body_max\": %.6g, "
                 "\"inside_body_mean\": %.6g, \"inside_body_max\": %.6g, \"body_self_overlap_mean\": %.6g, "
                 "\"body_self_overlap_max\": %.6g, \"inside_clear_mean\": %.6g, \"inside_clear_max\": %.6g}",
                 total.worn_sequences, total.lost_sequences, w->frames_off, w->off_body_max, w->inside_mean,
                 w->inside_max, w->overlap_mean, w->overlap_max, w->inside_clear_mean, w->inside_clear_max);
        snprintf(wear_text, sizeof wear_text,
                 "; worn: %u of %u garments lost, inside_body mean %.1f%% max %.1f%%, body_self_overlap mean %.1f%%",
                 total.lost_sequences, total.worn_sequences, 100.0 * w->inside_mean, 100.0 * w->inside_max,
                 100.0 * w->overlap_mean);
    }
#endif
    if (o.json && failed) {
        printf("{\"mve_cm\": null, \"collision_rate\": null, \"self_collision_rate\": null, \"ms_per_frame\": %.6g, "
               "\"frames\": %u, \"nan\": %s, \"max_edge_strain\": null, \"failed\": true, \"time_limited\": %s, "
               "\"wear\": null}\n",
               ms, total.frames, total.nan ? "true" : "false", total.time_limited ? "true" : "false");
    } else if (failed) {
        printf("total: %u sequences, %u frames: FAILED%s (no MVE for a failed run)\n", total.sequences, total.frames,
               total.nan ? ", a rollout went non-finite" : "");
    } else if (o.json) {
        printf("{\"mve_cm\": %.6g, \"collision_rate\": %.6g, \"self_collision_rate\": %.6g, \"ms_per_frame\": %.6g, "
               "\"frames\": %u, \"nan\": %s, \"max_edge_strain\": %.6g, \"collider_tokens\": %.6g, "
               "\"ccd_passes\": %.6g, \"overstretched_pct\": %.6g, \"gt_max_edge_strain\": %.6g, "
               "\"pushed_vertices\": %.6g, \"push_from_far_side\": %.6g, \"ccd_let_out\": %.6g, \"time_limited\": %s, "
               "\"ms_p50\": %s, \"ms_p99\": %s, \"ms_max\": %s, \"wear\": %s}\n",
               mve, coll, self, ms, total.frames, total.nan ? "true" : "false", total.max_strain, tokens, passes,
               total.overstretched_pct, total.gt_max_strain, pushed, push_far, let_out, total.time_limited ? "true" : "false",
               ms_p50, ms_p99, ms_max, wear_json);
    } else if (total.sequences > 0) {
        printf("total: %u sequences, %u frames, MVE %.3f cm, collision %.2f%%, self-collision %.2f%%, %.3f ms/frame "
               "(p50 %s, p99 %s, max %s), max edge strain %.3f (%.2f%% of edges over %.0f%%, reference %.3f), nan %s, "
               "collider tokens %.0f/frame%s%s\n",
               total.sequences, total.frames, mve, coll, self, ms, ms_p50, ms_p99, ms_max, total.max_strain,
               total.overstretched_pct, EVAL_OVERSTRETCH * 100, total.gt_max_strain, total.nan ? "yes" : "no", tokens,
               total.time_limited ? ", stopped by --time-limit" : "", wear_text);
    }
    free(total.frame_ms);
    weft_model_destroy(model);
    weft_context_destroy(ctx);
    return rc;
}
