/* One dataset sequence: build the scenario, simulate it with XPBD, validate every frame,
 * and write the arrays (.npy) and meta.json. */
#define _POSIX_C_SOURCE 200809L /* mkdir, rename */
#include "scene.h"

#include "npy_write.h"
#include "weft/wear.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

enum {
    ST_WALL_MS,
    ST_SUBSTEPS,
    ST_DETECTIONS,
    ST_CONTACTS,
    ST_CONTACTS_DROPPED,
    ST_CLAMPED,
    ST_MIN_SELF,
    ST_MIN_COLLIDER,
    ST_MAX_STRAIN,
    ST_ENERGY,
    ST_CCD_HITS,
    ST_TRI_HITS,
    ST_VALIDATE_MS,
    ST_RETRIED,
    ST_PATH,
    ST_INSIDE_BODY,
    ST_INSIDE_CLEAR,
    ST_SELF_EXEMPT,
    ST_TANGLED,
    ST_TANGLED_CLEAR,
    ST_COUNT
};
static const char *const stat_names[ST_COUNT] = {
    "wall_ms",   "substeps",   "detections",      "contacts", "contacts_dropped", "clamped",    "min_self_distance",
    "min_collider_distance", "max_strain", "elastic_energy", "ccd_hits", "intersection_hits", "validate_ms", "chord_safe_retry",
    "path_validated", "inside_body", "inside_clear", "self_exempt", "tangled", "tangled_clear"};

weft_sim_sequence_def weft_sim_default_sequence_def(void)
{
    weft_sim_sequence_def d = {0};
    d.scenario = WEFT_SIM_SCENARIO_DROP;
    d.seed = 1;
    d.frames = 240;
    d.substeps = 40;
    d.max_substeps = 80;
    d.fast_collider_factor = 8;
    d.cloth_vertices = 1024;
    d.validate = true;
    d.motion_speed = 1.0f;
    d.garment_retry = true;
    d.garment_kind = -1;
    d.garment_arm_spread = 0.3f;
    d.garment_retry_arm_spread = 0.3f;
    d.garment_retry_ease_in = 0.5f;
    d.garment_retry_amplitude = 0.75f;
    d.prefix_frames_min = 60;
    d.internal_cookie = WEFT_DEF_COOKIE;
    return d;
}

const char *weft_sim_split_of(const char *name)
{
    uint64_t h = 1469598103934665603ull ^ 0x5b11u;
    for (const char *c = name ? name : ""; *c; ++c) {
        h = (h ^ (unsigned char)*c) * 1099511628211ull;
    }
    h = (h ^ (h >> 30)) * 0xBF58476D1CE4E5B9ull;
    h = (h ^ (h >> 27)) * 0x94D049BB133111EBull;
    h = (h ^ (h >> 31)) % 10;
    return h < 8 ? "train" : (h == 8 ? "val" : "test");
}

/* A whole small file as a NUL-terminated string (NULL when unreadable or over 64 MiB). */
static char *read_text(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    char *text = NULL;
    long size = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
    if (size >= 0 && size < (64l << 20) && fseek(f, 0, SEEK_SET) == 0 && (text = malloc((size_t)size + 1))) {
        if (fread(text, 1, (size_t)size, f) != (size_t)size) {
            free(text);
            text = NULL;
        } else {
            text[size] = '\0';
        }
    }
    fclose(f);
    return text;
}

/* One of the three split names, by value, so the caller's pointer outlives the parsed JSON. */
static const char *split_constant(const cJSON *v)
{
    static const char *const names[] = {"train", "val", "test"};
    for (int i = 0; cJSON_IsString(v) && i < 3; ++i) {
        if (strcmp(v->valuestring, names[i]) == 0) {
            return names[i];
        }
    }
    return NULL;
}

const char *weft_sim_sequence_split(const char *dir)
{
    char path[4096];
    size_t len = dir ? strlen(dir) : 0;
    while (len > 1 && dir[len - 1] == '/') {
        --len;
    }
    if (len == 0 || len + 32 > sizeof path) {
        return NULL;
    }
    size_t base = len;
    while (base > 0 && dir[base - 1] != '/') {
        --base;
    }
    char name[256];
    snprintf(name, sizeof name, "%.*s", (int)(len - base), dir + base);
    /* 1. meta.json (packed sequences carry their split there) */
    snprintf(path, sizeof path, "%.*s/meta.json", (int)len, dir);
    char *text = read_text(path);
    cJSON *json = text ? cJSON_Parse(text) : NULL;
    const char *split = split_constant(cJSON_GetObjectItemCaseSensitive(json, "split"));
    cJSON_Delete(json);
    free(text);
    /* 2. the dataset's manifest.json, one folder up */
    if (!split) {
        snprintf(path, sizeof path, "%.*smanifest.json", (int)base, dir);
        text = base > 0 ? read_text(path) : read_text("manifest.json");
        json = text ? cJSON_Parse(text) : NULL;
        const cJSON *e;
        cJSON_ArrayForEach(e, cJSON_GetObjectItemCaseSensitive(json, "sequences"))
        {
            const cJSON *en = cJSON_GetObjectItemCaseSensitive(e, "name");
            if (!split && cJSON_IsString(en) && strcmp(en->valuestring, name) == 0) {
                split = split_constant(cJSON_GetObjectItemCaseSensitive(e, "split"));
            }
        }
        cJSON_Delete(json);
        free(text);
    }
    /* 3. the name's hash, as simgen assigns it */
    return split ? split : weft_sim_split_of(name);
}

const char *weft_sim_scenario_name(weft_sim_scenario s)
{
    static const char *const names[] = {"drop", "gripper", "garment"};
    return (unsigned)s < WEFT_SIM_SCENARIO_COUNT ? names[s] : "unknown";
}


static bool make_dir(const char *path)
{
    char buf[1024];
    size_t n = strlen(path);
    if (n == 0 || n >= sizeof buf) {
        return false;
    }
    memcpy(buf, path, n + 1);
    for (size_t i = 1; i <= n; ++i) {
        if (buf[i] == '/' || buf[i] == '\0') {
            char c = buf[i];
            buf[i] = '\0';
            if (mkdir(buf, 0777) != 0 && errno != EEXIST) {
                return false;
            }
            buf[i] = c;
        }
    }
    return true;
}

typedef struct run_buffers {
    float *cloth;     /* frames * nv * 3 */
    float *collider;  /* frames * nc * 3 */
    uint8_t *pinned;  /* frames * nv */
    float *stats;     /* frames * ST_COUNT (row 0 is the initial state) */
    float *path;      /* (max_substeps * fast_collider_factor + 1) * nv * 3: the solver's substep path of a frame */
    uint32_t *pin_idx;
    float *pin_tgt;
} run_buffers;

static void buffers_free(run_buffers *b)
{
    free(b->cloth);
    free(b->collider);
    free(b->pinned);
    free(b->stats);
    free(b->path);
    free(b->pin_idx);
    free(b->pin_tgt);
    *b = (run_buffers){0};
}

/* ---------------------------------------------------------------------------------------- */
/* Checkpoints (def.checkpoint_frames): out_dir/checkpoint.bin holds where the run stands, so a
 * long sequence survives the end of a job. Layout, native byte order (a checkpoint is for the
 * machine type that wrote it): the header below, then for frame > 0 the cloth of frames
 * 0..frame (f32), their stats rows (f32) and the solver's double positions and velocities at
 * `frame` (3 n f64 each), then an FNV-1a 64 hash of everything before it. The collider and the
 * pins of the finished frames are not stored: they are functions of the frame. */

#define CKPT_MAGIC "WEFTSIMC"
#define CKPT_VERSION 1u

typedef struct ckpt_header {
    char magic[8];
    uint32_t version;
    uint32_t round, substeps, attempts; /* the attempt it belongs to (round 1: the gentle garment retry) */
    uint32_t frame;                     /* last finished frame; 0: the attempt is to start from frame 1 */
    uint32_t nv, nc, frames_total;
    uint64_t fingerprint;
    uint32_t chord_retries, path_frames, ccd_hits, intersection_hits;
    double simulate_s, validate_s;
} ckpt_header;

typedef struct ckpt_run {
    const char *dir;           /* NULL: checkpoints off */
    uint32_t every;            /* def.checkpoint_frames */
    uint64_t fingerprint;
    double deadline_ms;        /* weft__now_ms() after which the call stops at a checkpoint (0: none) */
    uint32_t round, attempts;  /* of the attempt being simulated */
    const ckpt_header *resume; /* continue from it: b->cloth and b->stats rows 0..frame, xd and vd hold it */
    double *xd, *vd;           /* 3 n each: the solver state read or to be written */
    bool stopped;              /* out: the time limit ended the call at a checkpoint */
} ckpt_run;

static uint64_t fnv1a(uint64_t h, const void *data, size_t size)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < size; ++i) {
        h = (h ^ p[i]) * 1099511628211ull;
    }
    return h;
}

/* Everything of the def and the scene sizes that shapes the sequence; field by field, so
 * padding never enters it. */
static uint64_t def_fingerprint(const weft_sim_sequence_def *d, uint32_t nv, uint32_t nc, uint32_t T)
{
    uint64_t h = 1469598103934665603ull;
    const uint32_t u[] = {(uint32_t)d->scenario, d->frames, d->substeps, d->max_substeps, d->fast_collider_factor,
                          d->cloth_vertices, d->validate, d->garment_retry, d->checkpoint_frames, nv, nc, T};
    const float f[] = {d->motion_speed, d->garment_arm_spread, d->garment_retry_arm_spread, d->garment_retry_ease_in,
                       d->garment_retry_amplitude};
    h = fnv1a(h, &d->seed, sizeof d->seed);
    h = fnv1a(h, u, sizeof u);
    if (d->motion_path) { /* procedural sequences hash as before clips existed */
        h = fnv1a(h, d->motion_path, strlen(d->motion_path));
        h = fnv1a(h, &d->motion_start_s, sizeof d->motion_start_s);
        h = fnv1a(h, "projected body", 14); /* the reference on real motion (scene.c) */
    }
    if (d->garment_kind >= 0) {
        h = fnv1a(h, &d->garment_kind, sizeof d->garment_kind); /* the default draw hashes as before it existed */
    }
    if (d->character) {
        const weft_sim_character *c = d->character;
        h = fnv1a(h, c->name, strlen(c->name));
        h = fnv1a(h, &c->preroll, sizeof c->preroll);
        h = fnv1a(h, c->rest_positions, sizeof(float) * 3 * c->vertex_count);
        h = fnv1a(h, c->garment_positions, sizeof(float) * 3 * c->garment_vertex_count);
    }
    return fnv1a(h, f, sizeof f);
}

static void ckpt_path(char *path, size_t size, const char *dir, const char *suffix)
{
    snprintf(path, size, "%s/checkpoint.bin%s", dir, suffix);
}

/* Writes the checkpoint atomically (temporary file, then rename): a failed write leaves the
 * previous checkpoint in place. */
static bool ckpt_write(const ckpt_header *h, const run_buffers *b, const double *xd, const double *vd, const char *dir)
{
    char tmp[1100], fin[1100], suffix[32];
    snprintf(suffix, sizeof suffix, ".%ld.tmp", (long)getpid()); /* two runs on one folder never share it */
    ckpt_path(tmp, sizeof tmp, dir, suffix);
    ckpt_path(fin, sizeof fin, dir, "");
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        return false;
    }
    const size_t nv3 = 3 * (size_t)h->nv, rows = h->frame > 0 ? (size_t)h->frame + 1 : 0;
    struct {
        const void *p;
        size_t size;
    } parts[] = {{h, sizeof *h},
                 {b->cloth, sizeof(float) * nv3 * rows},
                 {b->stats, sizeof(float) * ST_COUNT * rows},
                 {xd, rows ? sizeof(double) * nv3 : 0},
                 {vd, rows ? sizeof(double) * nv3 : 0}};
    uint64_t hash = 1469598103934665603ull;
    bool ok = true;
    for (size_t k = 0; k < sizeof parts / sizeof parts[0]; ++k) {
        ok = ok && (parts[k].size == 0 || fwrite(parts[k].p, 1, parts[k].size, f) == parts[k].size);
        hash = fnv1a(hash, parts[k].p, parts[k].size);
    }
    ok = ok && fwrite(&hash, sizeof hash, 1, f) == 1;
    ok = (fclose(f) == 0) && ok;
    if (!ok || rename(tmp, fin) != 0) {
        remove(tmp);
        return false;
    }
    return true;
}

/* Reads a checkpoint that matches the fingerprint and sizes into h and the buffers (cloth and
 * stats rows 0..frame, xd and vd). false when there is none, or it is of another def, truncated
 * or corrupt: the run then starts over. */
static bool ckpt_read(const char *dir, uint64_t fingerprint, uint32_t nv, uint32_t nc, uint32_t T, ckpt_header *h,
                      run_buffers *b, double *xd, double *vd)
{
    char path[1100];
    ckpt_path(path, sizeof path, dir, "");
    FILE *f = fopen(path, "rb");
    if (!f) {
        return false;
    }
    bool ok = fread(h, sizeof *h, 1, f) == 1 && memcmp(h->magic, CKPT_MAGIC, 8) == 0 && h->version == CKPT_VERSION &&
              h->fingerprint == fingerprint && h->nv == nv && h->nc == nc && h->frames_total == T && h->frame < T &&
              h->round < 2 && h->substeps > 0;
    uint64_t hash = fnv1a(1469598103934665603ull, h, sizeof *h);
    if (ok) {
        const size_t nv3 = 3 * (size_t)nv, rows = h->frame > 0 ? (size_t)h->frame + 1 : 0;
        struct {
            void *p;
            size_t size;
        } parts[] = {{b->cloth, sizeof(float) * nv3 * rows},
                     {b->stats, sizeof(float) * ST_COUNT * rows},
                     {xd, rows ? sizeof(double) * nv3 : 0},
                     {vd, rows ? sizeof(double) * nv3 : 0}};
        for (size_t k = 0; ok && k < sizeof parts / sizeof parts[0]; ++k) {
            ok = parts[k].size == 0 || fread(parts[k].p, 1, parts[k].size, f) == parts[k].size;
            hash = fnv1a(hash, parts[k].p, parts[k].size);
        }
        uint64_t stored = 0;
        ok = ok && fread(&stored, sizeof stored, 1, f) == 1 && stored == hash && fgetc(f) == EOF;
    }
    fclose(f);
    return ok;
}

/* Certifies frame f. The chord between the output frames comes first: it is cheap and is
 * what a frame-level consumer (the model's CCD post-process) sees. When the chord grazes the
 * collider or the cloth, the recorded substep path (what the solver actually integrated,
 * piecewise linear) decides instead and *by_path is set; a curved path around a moving body
 * can be clean while its chord is not. */
static weft_result validate_frame(weft_sim_validator *val, const weft_garment *g, const run_buffers *b, uint32_t f,
                                  uint32_t nv, uint32_t nc, weft_sim_validation *v, bool *by_path)
{
    const float *c0 = b->collider + (size_t)(f - 1) * nc * 3, *c1 = b->collider + (size_t)f * nc * 3;
    *by_path = false;
    weft_result r = weft_sim_validator_check(val, b->cloth + (size_t)(f - 1) * nv * 3, b->cloth + (size_t)f * nv * 3,
                                             c0, c1, v);
    uint32_t states = weft__xpbd_recorded_states(g);
    if (r != WEFT_OK || (v->ccd_hits == 0 && v->intersection_hits == 0) || states < 2) {
        return r;
    }
    /* The path ends where the frame does: a move of the constraint stage after the solve (the max
     * distance, pins set to their targets, the floor) joins the last substep's straight motion. */
    memcpy(b->path + (size_t)(states - 1) * nv * 3, b->cloth + (size_t)f * nv * 3, sizeof(float) * 3 * nv);
    weft_sim_validation pv;
    r = weft_sim_validator_check_path(val, b->path, states, c0, c1, &pv);
    if (r == WEFT_OK) {
        /* the path is the motion the solver made: its verdict, and where it failed */
        *by_path = pv.ccd_hits == 0 && pv.intersection_hits == 0;
        *v = pv;
    }
    return r;
}

/* Says where frame f was rejected: the hit's first vertex at f and, on the avatar, the joint
 * that dominates the skinning of the body vertex nearest to it (a scan of the body, once per
 * rejected attempt). */
static void locate_hit(const xscene *sc, const run_buffers *b, uint32_t f, const weft_ccd_hit *hit,
                       weft_sim_sequence_result *res)
{
    const uint32_t nv = sc->cloth.nv, nc = sc->collider.nv;
    res->hit = *hit;
    memset(res->hit_position, 0, sizeof res->hit_position);
    res->hit_joint[0] = '\0';
    if (hit->type >= WEFT_CCD_TYPE_COUNT) {
        return;
    }
    const bool on_collider = hit->type == WEFT_CCD_FV;
    const float *p = on_collider ? b->collider + ((size_t)f * nc + hit->v[0]) * 3 : b->cloth + ((size_t)f * nv + hit->v[0]) * 3;
    memcpy(res->hit_position, p, sizeof res->hit_position);
    if (!sc->body) {
        return;
    }
    const float *body = b->collider + (size_t)f * nc * 3;
    uint32_t nearest = hit->v[0];
    if (!on_collider) {
        float best = INFINITY;
        for (uint32_t i = 0; i < nc; ++i) {
            const float *q = body + (size_t)i * 3;
            const float d = (q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) + (q[2] - p[2]) * (q[2] - p[2]);
            if (d < best) {
                best = d;
                nearest = i;
            }
        }
    }
    const float *w = weft_body_weights(sc->body) + (size_t)nearest * WEFT_BODY_JOINTS;
    uint32_t j = 0;
    for (uint32_t k = 1; k < WEFT_BODY_JOINTS; ++k) {
        j = w[k] > w[j] ? k : j;
    }
    snprintf(res->hit_joint, sizeof res->hit_joint, "%s", weft_joint_name(j));
}

/* The collider and the pins of frame f into the run's buffers (b->collider row f, b->pin_idx /
 * b->pin_tgt, pinned.npy's row f); returns the pin count. */
static uint32_t kinematics_at(const xscene *sc, run_buffers *b, uint32_t f)
{
    const uint32_t nv = sc->cloth.nv;
    float *c = b->collider + (size_t)f * sc->collider.nv * 3;
    xscene_collider_at(sc, f, c);
    const uint32_t np = xscene_pins_at(sc, f, c, b->pin_idx, b->pin_tgt);
    for (uint32_t k = 0; k < np; ++k) {
        b->pinned[(size_t)f * nv + b->pin_idx[k]] = 1;
    }
    return np;
}

/* Header of a checkpoint of the running attempt after frame f (0: the attempt's start). */
static ckpt_header ckpt_at(const ckpt_run *ck, const weft_sim_sequence_result *res, uint32_t substeps, uint32_t f,
                           uint32_t nv, uint32_t nc, uint32_t T)
{
    ckpt_header h = {.version = CKPT_VERSION, .round = ck->round, .substeps = substeps, .attempts = ck->attempts,
                     .frame = f, .nv = nv, .nc = nc, .frames_total = T, .fingerprint = ck->fingerprint,
                     .chord_retries = res->chord_retries, .path_frames = res->path_frames, .ccd_hits = res->ccd_hits,
                     .intersection_hits = res->intersection_hits, .simulate_s = res->simulate_s,
                     .validate_s = res->validate_s};
    memcpy(h.magic, CKPT_MAGIC, 8);
    return h;
}

/* Real motion: whether the constraint stage moved cloth vertex v after the solve (the max distance
 * pulling cloth the bounds held back, the floor): its position at frame f differs from the last
 * recorded substep's. Read before validate_frame, which joins the path to the frame. */
static bool moved_after_solve(const float *solved, const float *x, uint32_t v)
{
    if (!solved) {
        return false;
    }
    const float *p = solved + 3 * (size_t)v, *q = x + 3 * (size_t)v;
    return p[0] != q[0] || p[1] != q[1] || p[2] != q[2];
}

/* What a run keeps of its last frame done, rebuilt from that frame's recorded positions (the run's
 * first frame, a resumed run): near[2 nv, 3 nv) the squeeze zone, near[3 nv, 4 nv) the cloth
 * crossing itself. */
static weft_result last_frame_state(weft_wear *wear, weft_sim_validator *val, const xscene *sc, const run_buffers *b,
                                    uint32_t frame, uint8_t *near)
{
    const uint32_t nv = sc->cloth.nv, nc = sc->collider.nv;
    const float *bp = b->collider + (size_t)frame * nc * 3, *xp = b->cloth + (size_t)frame * nv * 3;
    weft_wear_frame scratch;
    uint32_t crossed = 0;
    weft_result r = weft_wear_measure(wear, bp, xp, xp, 1.0f, &scratch); /* the body's normals near_overlap reads */
    r = r != WEFT_OK ? r : weft_wear_near_overlap(wear, bp, WEFT_SIM_SQUEEZE_REACH, xp, nv, near + 2 * (size_t)nv);
    return r != WEFT_OK ? r : weft_sim_validator_tangled(val, xp, NULL, near + 3 * (size_t)nv, &crossed, NULL);
}

/* Real motion: the wear measures of frame f into its stats row (the cloth inside the body, and
 * inside where the body is clear), and the cloth the validator exempts from its cloth-cloth test:
 * near where the body squeezes it at f or at f - 1, moved by the constraint stage after the solve
 * (not under the bounds), and cloth that was crossing itself at the end of f - 1 (which the
 * validator let pass only where exempt: a tangle made there stays exempt while it stays crossed),
 * whose share goes into the row too. Runs before the frame is validated.
 * near[0, nv): exempt; [nv, 2 nv): near the squeeze at f; [2 nv, 3 nv): at *measured, the last
 * frame done; [3 nv, 4 nv): crossing itself at *measured (rebuilt by last_frame_state when
 * *measured is not f - 1: the run's first frame). */
static weft_result body_check(weft_wear *wear, weft_sim_validator *val, const weft_garment *g, const xscene *sc,
                              run_buffers *b, uint32_t f, uint8_t *near, const uint32_t *measured, weft_wear_frame *wf)
{
    const uint32_t nv = sc->cloth.nv, nc = sc->collider.nv;
    uint8_t *now = near + nv, *last = near + 2 * (size_t)nv, *tangled = near + 3 * (size_t)nv;
    weft_result r = *measured + 1 != f ? last_frame_state(wear, val, sc, b, f - 1, near) : WEFT_OK;
    const float *body = b->collider + (size_t)f * nc * 3, *xf = b->cloth + (size_t)f * nv * 3;
    r = r != WEFT_OK ? r : weft_wear_measure(wear, body, xf, xf, 1.0f, wf);
    r = r != WEFT_OK ? r : weft_wear_near_overlap(wear, body, WEFT_SIM_SQUEEZE_REACH, xf, nv, now);
    if (r != WEFT_OK) {
        return r;
    }
    const uint32_t states = weft__xpbd_recorded_states(g);
    const float *solved = states >= 2 ? b->path + (size_t)(states - 1) * nv * 3 : NULL;
    uint32_t exempt = 0;
    for (uint32_t v = 0; v < nv; ++v) {
        near[v] = now[v] | last[v] | tangled[v] | moved_after_solve(solved, xf, v);
        exempt += near[v];
    }
    float *row = b->stats + (size_t)f * ST_COUNT;
    row[ST_INSIDE_BODY] = (float)wf->inside_body;
    row[ST_INSIDE_CLEAR] = (float)wf->inside_clear;
    row[ST_SELF_EXEMPT] = (float)exempt / (float)nv;
    return WEFT_OK;
}

/* The wear measures' columns over stats rows 1..last into the result (real motion; 0 elsewhere). */
static void inside_summary(const run_buffers *b, size_t last, weft_sim_sequence_result *res)
{
    double sum = 0.0, worst = 0.0, clear = 0.0, exempt = 0.0, tangled = 0.0, tangled_clear = 0.0;
    for (size_t f = 1; f <= last; ++f) {
        const float *row = b->stats + f * ST_COUNT;
        sum += row[ST_INSIDE_BODY];
        worst = fmax(worst, row[ST_INSIDE_BODY]);
        clear = fmax(clear, row[ST_INSIDE_CLEAR]);
        exempt += row[ST_SELF_EXEMPT];
        tangled = fmax(tangled, row[ST_TANGLED]);
        tangled_clear = fmax(tangled_clear, row[ST_TANGLED_CLEAR]);
    }
    res->self_exempt_mean = last > 0 ? (float)(exempt / (double)last) : 0.0f;
    res->tangled_max = (float)tangled;
    res->tangled_clear_max = (float)tangled_clear;
    res->inside_body_mean = last > 0 ? (float)(sum / (double)last) : 0.0f;
    res->inside_body_max = (float)worst;
    res->inside_clear_max = (float)clear;
}

/* Simulates all frames at `substeps`; stops at the first validator hit. With checkpoints
 * (ck->dir), the state is saved every ck->every frames, the run continues from ck->resume when
 * given, and stops early (ck->stopped) at the first checkpoint after ck->deadline_ms. */
static weft_result simulate(weft_context *ctx, const xscene *sc, const weft_sim_sequence_def *def, uint32_t substeps,
                            run_buffers *b, weft_sim_sequence_result *res, ckpt_run *ck, weft_sim_progress_fn *progress,
                            void *user)
{
    /* Garments first drape for sc->preroll frames; those are simulated and validated like
     * the rest but not written. */
    const uint32_t nv = sc->cloth.nv, nc = sc->collider.nv, T = def->frames + sc->preroll;
    const weft_garment_def gd = xscene_garment_def(sc, substeps, def->fast_collider_factor);
    weft_garment *g = NULL;
    xscene_collider_at(sc, 0, b->collider);
    weft_result r = weft_garment_create(ctx, &gd, &g);
    if (r != WEFT_OK) {
        return r;
    }
    weft_sim_validator *val = NULL;
    weft_wear *wear = NULL;
    uint8_t *near_overlap = NULL;
    if (def->validate) {
        /* Motion capture: the validator certifies the cloth against itself, and the body is
         * checked by the wear measures (docs/REFSIM.md, Real motion). */
        r = sc->clip ? weft_sim_validator_create(ctx, sc->cloth.tris, sc->cloth.nt, nv, NULL, 0, 0, &val)
                     : weft_sim_validator_create(ctx, sc->cloth.tris, sc->cloth.nt, nv, sc->collider.tris,
                                                 sc->collider.nt, nc, &val);
        if (r == WEFT_OK && sc->clip) {
            r = weft_wear_create(sc->collider.tris, sc->collider.nt, nc, nv, &wear);
            /* exempt; near a squeeze now, at the last frame; crossed; pinched (near a squeeze now or
             * at the frame before, where a crossing does not count) */
            near_overlap = calloc(5 * (size_t)nv, 1);
            r = r != WEFT_OK ? r : near_overlap ? weft_sim_validator_set_self_exempt(val, near_overlap)
                                                : weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "simgen: out of memory");
            /* a skirt or dress: where the body squeezed the cloth at the frame before, the cloth
             * keeps its bounds against the body's projection (REFSIM.md, Real motion) */
            if (r == WEFT_OK && weft_wear_reference_holds_squeeze(sc->cloth_kind)) {
                r = weft__xpbd_set_bounded_projection(g, near_overlap + 2 * (size_t)nv);
            }
            /* the cloth crossing itself at the frame before is untangled (REFSIM.md, Real motion) */
            if (r == WEFT_OK) {
                r = weft__xpbd_set_untangle(g, near_overlap + 3 * (size_t)nv);
            }
        }
        if (r != WEFT_OK) {
            free(near_overlap);
            weft_wear_destroy(wear);
            weft_sim_validator_destroy(val);
            weft_garment_destroy(g);
            return r;
        }
        if (g->part_mask) { /* body parts: certified against the parts each vertex collides with */
            r = weft_sim_validator_set_parts(val, g->part_mask, g->ctri_bits);
        }
        r = r != WEFT_OK ? r : weft__xpbd_record_substeps(g, b->path, def->max_substeps * def->fast_collider_factor);
        if (r != WEFT_OK) {
            free(near_overlap);
            weft_wear_destroy(wear);
            weft_sim_validator_destroy(val);
            weft_garment_destroy(g);
            return r;
        }
    }
    memcpy(b->cloth, sc->cloth_init, sizeof(float) * 3 * nv);
    const size_t kept = ck->resume ? (size_t)ck->resume->frame + 1 : 0; /* stats rows the checkpoint restored */
    memset(b->stats + kept * ST_COUNT, 0, sizeof(float) * ST_COUNT * (T - kept));
    memset(b->pinned, 0, (size_t)T * nv);
    res->ccd_hits = res->intersection_hits = 0;
    res->inside_clear_rejected = res->tangled_rejected = false;
    res->rejected_share = 0.0f;
    res->first_hit_frame = -1;
    locate_hit(sc, b, 0, &(weft_ccd_hit){.type = WEFT_CCD_TYPE_COUNT}, res);
    res->chord_retries = res->path_frames = 0;
    res->simulate_s = res->validate_s = 0.0;
    uint32_t f_first = 1;
    uint32_t measured = UINT32_MAX - 1; /* body_check's last frame: none yet */
    if (ck->resume) {
        /* Continue after the checkpoint's frame: its kinematics again (functions of the frame),
         * its recorded frames and counters, and the solver's exact state. */
        const ckpt_header *h = ck->resume;
        for (uint32_t f = 1; f <= h->frame; ++f) {
            (void)kinematics_at(sc, b, f);
        }
        res->chord_retries = h->chord_retries;
        res->path_frames = h->path_frames;
        res->ccd_hits = h->ccd_hits;
        res->intersection_hits = h->intersection_hits;
        res->simulate_s = h->simulate_s;
        res->validate_s = h->validate_s;
        res->resumed_frame = h->frame;
        r = weft_garment_set_state(g, b->cloth + (size_t)h->frame * nv * 3, b->cloth + (size_t)(h->frame - 1) * nv * 3);
        if (r == WEFT_OK && nc > 0) {
            r = weft_garment_set_collider_current(g, b->collider + (size_t)h->frame * nc * 3);
        }
        if (r == WEFT_OK) {
            r = weft__xpbd_import_state(g, ck->xd, ck->vd);
        }
        if (r == WEFT_OK && wear && h->frame > 0) { /* the squeeze zone the next step holds, as a continued run has it
                                                      (a fresh run's first step holds none) */
            r = last_frame_state(wear, val, sc, b, h->frame, near_overlap);
            measured = h->frame;
        }
        f_first = h->frame + 1;
        ck->resume = NULL;
    } else if (ck->dir) {
        /* A checkpoint at the attempt's start: a run stopped before its first frame checkpoint
         * resumes this attempt, not an earlier one. */
        const ckpt_header h = ckpt_at(ck, res, substeps, 0, nv, nc, T);
        if (!ckpt_write(&h, b, NULL, NULL, ck->dir)) {
            r = weft__fail(WEFT_ERROR_IO, "weft_sim_generate: writing the checkpoint into '%s' failed", ck->dir);
        }
    }
    for (uint32_t f = f_first; f < T && r == WEFT_OK; ++f) {
        if (ck->dir && f > 1 && (f - 1) % ck->every == 0) {
            weft__xpbd_forget_caches(g); /* as a run continued from the checkpoint after f - 1 has them */
        }
        const uint32_t np = kinematics_at(sc, b, f);
        const float *cnext = b->collider + (size_t)f * nc * 3;
        double t0 = weft__now_ms();
        r = weft_garment_set_collider(g, cnext);
        if (r == WEFT_OK) {
            r = weft_garment_set_pins(g, b->pin_idx, b->pin_tgt, np);
        }
        if (r == WEFT_OK) {
            r = weft_garment_step(g);
        }
        if (r != WEFT_OK) {
            break;
        }
        double t1 = weft__now_ms();
        memcpy(b->cloth + (size_t)f * nv * 3, weft_garment_positions(g), sizeof(float) * 3 * nv);
        xpbd_frame_stats st = weft__xpbd_last_stats(g);
        float *row = b->stats + (size_t)f * ST_COUNT;
        row[ST_WALL_MS] = (float)(t1 - t0);
        row[ST_SUBSTEPS] = (float)st.substeps;
        row[ST_DETECTIONS] = (float)st.detections;
        row[ST_CONTACTS] = (float)st.contacts;
        row[ST_CONTACTS_DROPPED] = (float)st.contacts_dropped;
        row[ST_CLAMPED] = (float)st.clamped;
        row[ST_MIN_SELF] = (float)st.min_self_distance;
        row[ST_MIN_COLLIDER] = (float)st.min_collider_distance;
        row[ST_MAX_STRAIN] = (float)st.max_strain;
        row[ST_ENERGY] = (float)st.elastic_energy;
        res->simulate_s += (t1 - t0) / 1000.0;
        weft_wear_frame wf = {0};
        if (wear && (r = body_check(wear, val, g, sc, b, f, near_overlap, &measured, &wf)) != WEFT_OK) {
            break;
        }
        if (val) {
            double t2 = t1;
            weft_sim_validation v;
            bool by_path = false;
            r = validate_frame(val, g, b, f, nv, nc, &v, &by_path);
            if (r == WEFT_OK && (v.ccd_hits || v.intersection_hits)) {
                /* Neither the chord nor the substep path is clean: redo the frame with one
                 * proximity pass for the whole frame (chord-safe by construction). */
                r = weft__xpbd_retry_chord_safe(g, b->cloth + (size_t)(f - 1) * nv * 3,
                                                b->cloth + (size_t)(f >= 2 ? f - 2 : 0) * nv * 3,
                                                b->collider + (size_t)(f - 1) * nc * 3);
                if (r == WEFT_OK) {
                    r = weft_garment_set_collider(g, cnext);
                }
                if (r == WEFT_OK) {
                    r = weft_garment_set_pins(g, b->pin_idx, b->pin_tgt, np);
                }
                if (r == WEFT_OK) {
                    r = weft_garment_step(g);
                }
                if (r != WEFT_OK) {
                    break;
                }
                memcpy(b->cloth + (size_t)f * nv * 3, weft_garment_positions(g), sizeof(float) * 3 * nv);
                if (wear) { /* the exempt set of the frame as redone */
                    r = body_check(wear, val, g, sc, b, f, near_overlap, &measured, &wf);
                }
                if (r == WEFT_OK) {
                    r = validate_frame(val, g, b, f, nv, nc, &v, &by_path);
                }
                st = weft__xpbd_last_stats(g);
                row[ST_DETECTIONS] = (float)st.detections;
                row[ST_CONTACTS] = (float)st.contacts;
                row[ST_CLAMPED] = (float)st.clamped;
                row[ST_MIN_SELF] = (float)st.min_self_distance;
                row[ST_MIN_COLLIDER] = (float)st.min_collider_distance;
                row[ST_MAX_STRAIN] = (float)st.max_strain;
                row[ST_ENERGY] = (float)st.elastic_energy;
                row[ST_RETRIED] = 1.0f;
                res->chord_retries++;
            }
            t2 = weft__now_ms();
            row[ST_CCD_HITS] = (float)v.ccd_hits;
            row[ST_TRI_HITS] = (float)v.intersection_hits;
            row[ST_VALIDATE_MS] = (float)(t2 - t1);
            row[ST_PATH] = by_path ? 1.0f : 0.0f;
            res->validate_s += (t2 - t1) / 1000.0;
            res->ccd_hits += v.ccd_hits;
            res->intersection_hits += v.intersection_hits;
            res->path_frames += by_path;
            if (r != WEFT_OK) {
                break;
            }
            if ((v.ccd_hits || v.intersection_hits) && res->first_hit_frame < 0) {
                res->first_hit_frame = (int32_t)f;
                locate_hit(sc, b, f, &v.hit, res);
                break; /* rejected: no point simulating further */
            }
            if (wear && wf.inside_clear > WEFT_SIM_INSIDE_CLEAR_MAX && res->first_hit_frame < 0) {
                res->first_hit_frame = (int32_t)f;
                res->inside_clear_rejected = true;
                res->rejected_share = (float)wf.inside_clear;
                break; /* cloth inside the body where the body does not overlap itself */
            }
        }
        if (wear) {
            /* frame f is the last one now: its squeeze zone, and the cloth crossing itself there,
             * counted where the body does not pinch it (near a squeeze at f or f - 1) */
            uint32_t crossed = 0, crossed_clear = 0;
            uint8_t *pinched = near_overlap + 4 * (size_t)nv;
            for (uint32_t v = 0; v < nv; ++v) {
                pinched[v] = near_overlap[nv + v] | near_overlap[2 * (size_t)nv + v];
            }
            memcpy(near_overlap + 2 * (size_t)nv, near_overlap + nv, nv);
            r = weft_sim_validator_tangled(val, b->cloth + (size_t)f * nv * 3, pinched, near_overlap + 3 * (size_t)nv,
                                           &crossed, &crossed_clear);
            b->stats[(size_t)f * ST_COUNT + ST_TANGLED] = (float)crossed / (float)nv;
            b->stats[(size_t)f * ST_COUNT + ST_TANGLED_CLEAR] = (float)crossed_clear / (float)nv;
            measured = f;
            if (r != WEFT_OK) {
                break;
            }
            if ((double)crossed_clear > WEFT_SIM_TANGLED_MAX * nv && res->first_hit_frame < 0) {
                res->first_hit_frame = (int32_t)f;
                res->tangled_rejected = true;
                res->rejected_share = (float)crossed_clear / (float)nv;
                break; /* a tangle over the limit: not ground truth, however it came about */
            }
        }
        if (progress) {
            progress(f, T - 1, user);
        }
        if (ck->dir && f % ck->every == 0 && f + 1 < T) {
            r = weft__xpbd_export_state(g, ck->xd, ck->vd);
            const ckpt_header h = ckpt_at(ck, res, substeps, f, nv, nc, T);
            if (r == WEFT_OK && !ckpt_write(&h, b, ck->xd, ck->vd, ck->dir)) {
                r = weft__fail(WEFT_ERROR_IO, "weft_sim_generate: writing the checkpoint into '%s' failed", ck->dir);
            }
            if (r == WEFT_OK && ck->deadline_ms > 0.0 && weft__now_ms() >= ck->deadline_ms) {
                ck->stopped = true;
                break;
            }
        }
    }
    free(near_overlap);
    weft_wear_destroy(wear);
    weft_sim_validator_destroy(val);
    weft_garment_destroy(g);
    return r;
}

static cJSON *num_obj(cJSON *parent, const char *name)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddItemToObject(parent, name, o);
    return o;
}

/* weft_ccd_type in meta.json, and what its four vertex indices refer to. */
static const char *const hit_type_names[WEFT_CCD_TYPE_COUNT] = {"vf", "ee", "fv", "self_vf", "self_ee"};
static const char *const hit_type_vertices[WEFT_CCD_TYPE_COUNT] = {
    "cloth vertex, collider triangle", "cloth edge, collider edge", "collider vertex, cloth triangle",
    "cloth vertex, cloth triangle", "cloth edge, cloth edge"};

static bool write_meta(const char *dir, const xscene *sc, const weft_sim_sequence_def *def,
                       const weft_sim_sequence_result *res)
{
    xpbd_params p = xpbd_default_params();
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "scenario", weft_sim_scenario_name(def->scenario));
    cJSON_AddStringToObject(m, "description", res->description);
    cJSON_AddNumberToObject(m, "seed", (double)def->seed);
    cJSON_AddBoolToObject(m, "accepted", res->accepted);
    cJSON_AddNumberToObject(m, "frames", res->frames);
    if (res->truncated) {
        /* the frames before the one the validator rejected (validator.first_hit_frame) */
        cJSON_AddBoolToObject(m, "truncated", true);
        cJSON_AddNumberToObject(m, "planned_frames", def->frames);
    }
    cJSON_AddNumberToObject(m, "frame_dt", 1.0 / 60.0);
    cJSON_AddStringToObject(m, "units", "m, s, kg; Y up");
    cJSON_AddStringToObject(m, "solver", "xpbd small steps, one Gauss-Seidel pass per substep, double precision");
    cJSON_AddNumberToObject(m, "substeps", res->substeps_used);
    cJSON_AddNumberToObject(m, "attempts", res->attempts);
    cJSON_AddNumberToObject(m, "chord_safe_retries", res->chord_retries);
    cJSON_AddNumberToObject(m, "path_validated_frames", res->path_frames);
    cJSON_AddNumberToObject(m, "motion_speed", def->motion_speed);
    if (def->split) {
        cJSON_AddStringToObject(m, "split", def->split);
    }
    if (sc->clip) {
        const char *base = strrchr(def->motion_path, '/');
        cJSON *mo = num_obj(m, "mocap");
        cJSON_AddStringToObject(mo, "file", base ? base + 1 : def->motion_path);
        cJSON_AddStringToObject(mo, "clip", sc->clip->name);
        cJSON_AddNumberToObject(mo, "start_s", def->motion_start_s);
        cJSON_AddNumberToObject(mo, "fps", sc->clip->fps);
        cJSON_AddNumberToObject(mo, "turned_rad", -sc->clip_yaw);
        cJSON_AddStringToObject(mo, "body",
                                "the body's contacts projected each substep (cloth inside or within the contact radius "
                                "moves out along the nearest surface's pseudonormal; for a skirt or dress, where the body "
                                "squeezed the cloth at the frame before, the cloth keeps its cloth-cloth bounds after "
                                "it), then the cloth found crossing itself at the frame before untangled (each crossing "
                                "edge's end on the side that shortens the intersection contour goes back through the "
                                "triangle), the floor and, for a T-shirt, the "
                                "worn-garment recipe's max distance (inside the substeps and after them; a skirt or "
                                "dress hangs from its waistband), no push; the validator "
                                "certifies the cloth against itself except near where the body squeezes it, where the "
                                "max distance or the floor moved it after the solve, and where it still crosses itself "
                                "from such a place (stats self_exempt, tangled), and a frame with cloth crossing itself "
                                "outside where the body pinches it (tangled_clear) or inside the body "
                                "where the body does not overlap itself (inside_clear) over the limit rejects the "
                                "sequence; no arm spread");
        /* the max distance the reference ran with: a T-shirt's, none for a skirt or dress */
        cJSON_AddNumberToObject(mo, "max_distance_m", xscene_garment_def(sc, def->substeps, 1).tethers.distance);
        cJSON_AddNumberToObject(mo, "inside_clear_limit", WEFT_SIM_INSIDE_CLEAR_MAX);
        cJSON_AddNumberToObject(mo, "inside_body_mean", res->inside_body_mean);
        cJSON_AddNumberToObject(mo, "inside_body_max", res->inside_body_max);
        cJSON_AddNumberToObject(mo, "inside_clear_max", res->inside_clear_max);
        cJSON_AddNumberToObject(mo, "self_exempt_mean", res->self_exempt_mean);
        cJSON_AddNumberToObject(mo, "tangled_max", res->tangled_max);
        cJSON_AddNumberToObject(mo, "tangled_clear_max", res->tangled_clear_max);
        cJSON_AddNumberToObject(mo, "tangled_limit", WEFT_SIM_TANGLED_MAX);
        cJSON_AddBoolToObject(mo, "tangled_rejected", res->tangled_rejected);
        cJSON_AddBoolToObject(mo, "inside_clear_rejected", res->inside_clear_rejected);
        if (res->tangled_rejected || res->inside_clear_rejected) {
            cJSON_AddNumberToObject(mo, "rejected_share", res->rejected_share);
        }
    }
    if (sc->character) {
        cJSON *co = num_obj(m, "character");
        cJSON_AddStringToObject(co, "name", sc->character->name);
        cJSON_AddNumberToObject(co, "vertices", sc->character->vertex_count);
        cJSON_AddNumberToObject(co, "triangles", sc->character->triangle_count);
        cJSON_AddNumberToObject(co, "preroll_frames", sc->preroll);
        cJSON_AddBoolToObject(co, "body_parts", sc->parts != NULL);
    }
    if (def->checkpoint_frames) {
        /* the solver's candidate lists restart at these frames (weft_sim_sequence_def) */
        cJSON_AddNumberToObject(m, "checkpoint_frames", def->checkpoint_frames);
    }
    char seed_text[32];
    snprintf(seed_text, sizeof seed_text, "%llu", (unsigned long long)def->seed);
    cJSON_AddStringToObject(m, "seed_u64", seed_text);
    cJSON_AddStringToObject(m, "weft_version", weft_version_string());
    cJSON *val = num_obj(m, "validator");
    cJSON_AddNumberToObject(val, "ccd_hits", res->ccd_hits);
    cJSON_AddNumberToObject(val, "intersection_hits", res->intersection_hits);
    cJSON_AddNumberToObject(val, "first_hit_frame", res->first_hit_frame);
    if (res->hit.type < WEFT_CCD_TYPE_COUNT) {
        /* Where the last attempt failed, so rejections can be told apart without a rerun. */
        cJSON *hit = num_obj(val, "first_hit");
        cJSON_AddStringToObject(hit, "type", hit_type_names[res->hit.type]);
        cJSON_AddStringToObject(hit, "vertices_are", hit_type_vertices[res->hit.type]);
        const int vi[4] = {(int)res->hit.v[0], (int)res->hit.v[1], (int)res->hit.v[2], (int)res->hit.v[3]};
        cJSON_AddItemToObject(hit, "vertices", cJSON_CreateIntArray(vi, 4));
        cJSON_AddItemToObject(hit, "position", cJSON_CreateFloatArray(res->hit_position, 3));
        if (res->hit_joint[0]) {
            cJSON_AddStringToObject(hit, "body_joint", res->hit_joint);
        }
    }
    cJSON_AddNumberToObject(val, "tolerance_m", WEFT_SIM_VALIDATOR_TOLERANCE);
    cJSON_AddBoolToObject(val, "run", def->validate);
    cJSON_AddStringToObject(val, "method", "weft_ccd five-type CCD over the frame chord, else over the substep path; "
                                           "exact triangle intersection at every frame");
    cJSON *mat = num_obj(m, "material");
    cJSON_AddNumberToObject(mat, "youngs_modulus", p.youngs_modulus);
    cJSON_AddNumberToObject(mat, "poisson_ratio", p.poisson_ratio);
    cJSON_AddNumberToObject(mat, "thickness", p.thickness);
    cJSON_AddNumberToObject(mat, "areal_density", p.areal_density);
    cJSON_AddNumberToObject(mat, "compression_scale", p.compression_scale);
    cJSON_AddNumberToObject(mat, "shear_scale", p.shear_scale);
    cJSON_AddNumberToObject(mat, "friction", p.friction);
    cJSON_AddStringToObject(mat, "membrane", "baraff-witkin warp/weft stretch + shear (GIPC form)");
    cJSON_AddStringToObject(mat, "bending", "signed dihedral, k_b |e| (theta - theta0)^2, k_b = E h^3 / (24 (1 - nu^2))");
    cJSON_AddNumberToObject(mat, "damping", 0.0);
    cJSON *ct = num_obj(m, "contact");
    cJSON_AddNumberToObject(ct, "self_radius", p.self_radius);
    cJSON_AddNumberToObject(ct, "collider_radius", p.collider_radius);
    cJSON_AddNumberToObject(ct, "query_radius_min", p.query_radius);
    cJSON_AddNumberToObject(ct, "bound_gamma", p.bound_gamma);
    cJSON_AddNumberToObject(ct, "detect_window", p.detect_window);
    if (sc->scenario == WEFT_SIM_SCENARIO_GARMENT && !sc->character) {
        cJSON *gm = num_obj(m, "garment");
        cJSON_AddStringToObject(gm, "motion", weft_motion_name(sc->motion.motion));
        cJSON_AddNumberToObject(gm, "motion_speed", sc->motion.speed);
        cJSON_AddNumberToObject(gm, "motion_amplitude", sc->motion.amplitude);
        cJSON_AddNumberToObject(gm, "arm_spread", sc->motion.arm_spread);
        cJSON_AddNumberToObject(gm, "ease_in_s", sc->ease_in_s);
        cJSON_AddBoolToObject(gm, "gentle_retry", res->gentle);
        if (def->garment_kind >= 0) {
            /* the def chose the garment (weft_sim_sequence_def.garment_kind), not the seed */
            cJSON_AddStringToObject(gm, "garment_kind", weft_cloth_kind_name((weft_cloth_kind)def->garment_kind));
        }
        cJSON_AddNumberToObject(gm, "drape_preroll_frames", sc->preroll);
        cJSON_AddStringToObject(gm, "drape",
                                "the body blends from its bind pose to the motion's first pose over the first half of "
                                "the pre-roll and holds it for the second half; recording starts after it");
        cJSON_AddNumberToObject(gm, "waistband_vertices", sc->band_count);
        cJSON_AddNumberToObject(gm, "waistband_released", sc->band_released);
        cJSON_AddNumberToObject(gm, "clearance_m", sc->garment_clearance);
        if (sc->band_count) {
            cJSON_AddStringToObject(gm, "waistband",
                                    "the top ring is pinned to the body (bind-pose offset in the closest body "
                                    "triangle's frame), as an elastic band; pinned.npy marks it; vertices an arm comes within "
                                    "4 cm of during the pre-roll are left free (waistband_released)");
        }
    }
    cJSON *cl = num_obj(m, "cloth");
    cJSON_AddNumberToObject(cl, "vertices", sc->cloth.nv);
    cJSON_AddNumberToObject(cl, "triangles", sc->cloth.nt);
    cJSON *co = num_obj(m, "collider");
    cJSON_AddNumberToObject(co, "vertices", sc->collider.nv);
    cJSON_AddNumberToObject(co, "triangles", sc->collider.nt);
    cJSON_AddNumberToObject(co, "animated_from_vertex", sc->moving_begin);
    cJSON_AddStringToObject(co, "objects", sc->objects);
    if (sc->scenario == WEFT_SIM_SCENARIO_GRIPPER) {
        cJSON *gr = num_obj(m, "gripper");
        cJSON_AddNumberToObject(gr, "grasped_vertices", sc->grasp_count);
        cJSON_AddNumberToObject(gr, "lift", sc->lift);
        cJSON_AddNumberToObject(gr, "move_x", sc->move[0]);
        cJSON_AddNumberToObject(gr, "move_z", sc->move[1]);
        cJSON_AddNumberToObject(gr, "frame_close", sc->f_close);
        cJSON_AddNumberToObject(gr, "frame_lifted", sc->f_lifted);
        cJSON_AddNumberToObject(gr, "frame_moved", sc->f_moved);
        cJSON_AddNumberToObject(gr, "frame_lowered", sc->f_lowered);
        cJSON_AddNumberToObject(gr, "frame_release", sc->f_release);
        cJSON_AddNumberToObject(gr, "frame_open", sc->f_open);
        cJSON_AddStringToObject(gr, "attachment",
                                "vertices within 12 mm of the grasp point follow the gripper (pins) from frame_close+1 "
                                "to frame_release");
    }
    cJSON *tm = num_obj(m, "timings");
    cJSON_AddNumberToObject(tm, "simulate_s", res->simulate_s);
    cJSON_AddNumberToObject(tm, "validate_s", res->validate_s);
    /* per frame the last attempt stepped: the pre-roll and the recorded frames, up to a rejecting one */
    const double stepped = res->first_hit_frame >= 0 ? (double)res->first_hit_frame : (double)(def->frames + sc->preroll - 1);
    cJSON_AddNumberToObject(tm, "ms_per_frame", stepped > 0.0 ? 1000.0 * res->simulate_s / stepped : 0.0);
    cJSON *cols = cJSON_CreateArray();
    for (int i = 0; i < ST_COUNT; ++i) {
        cJSON_AddItemToArray(cols, cJSON_CreateString(stat_names[i]));
    }
    cJSON_AddItemToObject(m, "stats_columns", cols);
    cJSON *files = cJSON_CreateObject();
    if (res->accepted) {
        cJSON_AddStringToObject(files, "cloth_pos", "cloth_pos.npy [T,N,3] f32");
        cJSON_AddStringToObject(files, "rest_pos", "rest_pos.npy [N,3] f32");
        cJSON_AddStringToObject(files, "faces", "faces.npy [F,3] i32");
        cJSON_AddStringToObject(files, "collider_pos", "collider_pos.npy [T,M,3] f32");
        cJSON_AddStringToObject(files, "collider_faces", "collider_faces.npy [G,3] i32");
        cJSON_AddStringToObject(files, "pinned", "pinned.npy [T,N] u8");
        cJSON_AddStringToObject(files, "stats", "stats.npy [T,K] f32 (row 0 of a sequence without pre-roll is zeros)");
    }
    cJSON_AddItemToObject(m, "files", files);
    char *text = cJSON_Print(m);
    cJSON_Delete(m);
    if (!text) {
        return false;
    }
    char tmp[1100], fin[1100];
    snprintf(tmp, sizeof tmp, "%s/meta.json.tmp", dir);
    snprintf(fin, sizeof fin, "%s/meta.json", dir);
    FILE *f = fopen(tmp, "wb");
    bool ok = f && fputs(text, f) >= 0 && fputc('\n', f) != EOF;
    ok = (f && fclose(f) == 0) && ok;
    cJSON_free(text);
    return ok && rename(tmp, fin) == 0;
}

/* The recorded frames (res->frames: the def's, or a truncated window's first ones) after the
 * pre-roll. */
static bool write_arrays(const char *dir, const xscene *sc, const weft_sim_sequence_result *res, const run_buffers *b)
{
    char path[1100];
    const uint64_t T = res->frames, nv = sc->cloth.nv, nc = sc->collider.nv, off = sc->preroll;
    bool ok = true;
    uint64_t s2[2] = {nv, 3}, s3[3] = {T, nv, 3};
    snprintf(path, sizeof path, "%s/rest_pos.npy", dir);
    ok = ok && weft_npy_write_file(path, "<f4", s2, 2, sc->cloth.pos, sizeof(float) * 3 * nv);
    snprintf(path, sizeof path, "%s/cloth_pos.npy", dir);
    ok = ok && weft_npy_write_file(path, "<f4", s3, 3, b->cloth + off * nv * 3, sizeof(float) * 3 * nv * T);
    uint64_t sf[2] = {sc->cloth.nt, 3};
    snprintf(path, sizeof path, "%s/faces.npy", dir);
    ok = ok && weft_npy_write_file(path, "<i4", sf, 2, sc->cloth.tris, sizeof(uint32_t) * 3 * sc->cloth.nt);
    uint64_t sc3[3] = {T, nc, 3};
    snprintf(path, sizeof path, "%s/collider_pos.npy", dir);
    ok = ok && weft_npy_write_file(path, "<f4", sc3, 3, b->collider + off * nc * 3, sizeof(float) * 3 * nc * T);
    uint64_t scf[2] = {sc->collider.nt, 3};
    snprintf(path, sizeof path, "%s/collider_faces.npy", dir);
    ok = ok && weft_npy_write_file(path, "<i4", scf, 2, sc->collider.tris, sizeof(uint32_t) * 3 * sc->collider.nt);
    uint64_t sp[2] = {T, nv};
    snprintf(path, sizeof path, "%s/pinned.npy", dir);
    ok = ok && weft_npy_write_file(path, "|u1", sp, 2, b->pinned + off * nv, (size_t)T * nv);
    uint64_t ss[2] = {T, ST_COUNT};
    snprintf(path, sizeof path, "%s/stats.npy", dir);
    ok = ok && weft_npy_write_file(path, "<f4", ss, 2, b->stats + off * ST_COUNT, sizeof(float) * ST_COUNT * T);
    return ok;
}

/* Each field of a sequence def against its range; a failure names the field, its value and the
 * range. */
static weft_result check_sequence_def(const weft_sim_sequence_def *d, const char *out_dir)
{
#define WEFT_SEQ_BAD(cond, ...)                                                                   \
    do {                                                                                          \
        if (cond) {                                                                               \
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_sim_generate: " __VA_ARGS__);    \
        }                                                                                         \
    } while (0)
    WEFT_SEQ_BAD((unsigned)d->scenario >= WEFT_SIM_SCENARIO_COUNT, "scenario %u is not a weft_sim_scenario",
                 (unsigned)d->scenario);
    WEFT_SEQ_BAD(d->frames < 2 || d->frames > 100000, "frames %u outside [2, 100000]", d->frames);
    WEFT_SEQ_BAD(d->substeps == 0 || d->substeps > 1000, "substeps %u outside [1, 1000]", d->substeps);
    WEFT_SEQ_BAD(d->max_substeps < d->substeps || d->max_substeps > 1000,
                 "max_substeps %u outside [substeps = %u, 1000]", d->max_substeps, d->substeps);
    WEFT_SEQ_BAD(d->fast_collider_factor < 1 || d->fast_collider_factor > 16, "fast_collider_factor %u outside [1, 16]",
                 d->fast_collider_factor);
    WEFT_SEQ_BAD(d->max_substeps * d->fast_collider_factor > 4000,
                 "max_substeps x fast_collider_factor = %u x %u is over 4000", d->max_substeps,
                 d->fast_collider_factor);
    WEFT_SEQ_BAD(d->cloth_vertices < 16 || d->cloth_vertices > 200000, "cloth_vertices %u outside [16, 200000]",
                 d->cloth_vertices);
    WEFT_SEQ_BAD(strlen(out_dir) > 900, "out_dir is %zu characters long (at most 900)", strlen(out_dir));
    WEFT_SEQ_BAD(!(d->motion_speed >= 0.1f && d->motion_speed <= 10.0f), "motion_speed %g outside [0.1, 10]",
                 (double)d->motion_speed);
    WEFT_SEQ_BAD(!(d->garment_retry_arm_spread >= 0.0f && d->garment_retry_arm_spread <= 0.8f),
                 "garment_retry_arm_spread %g outside [0, 0.8]", (double)d->garment_retry_arm_spread);
    WEFT_SEQ_BAD(!(d->garment_arm_spread >= 0.0f && d->garment_arm_spread + d->garment_retry_arm_spread <= 0.8f),
                 "garment_arm_spread %g: must be >= 0 and, plus garment_retry_arm_spread %g, at most 0.8",
                 (double)d->garment_arm_spread, (double)d->garment_retry_arm_spread);
    WEFT_SEQ_BAD(!(d->garment_retry_ease_in >= 0.0f && d->garment_retry_ease_in <= 2.0f),
                 "garment_retry_ease_in %g outside [0, 2]", (double)d->garment_retry_ease_in);
    WEFT_SEQ_BAD(!(d->garment_retry_amplitude >= 0.1f && d->garment_retry_amplitude <= 1.0f),
                 "garment_retry_amplitude %g outside [0.1, 1]", (double)d->garment_retry_amplitude);
    WEFT_SEQ_BAD(!(d->garment_kind == -1 || d->garment_kind == WEFT_CLOTH_TSHIRT || d->garment_kind == WEFT_CLOTH_SKIRT ||
                   d->garment_kind == WEFT_CLOTH_DRESS),
                 "garment_kind %d is not -1 (any), tshirt, skirt or dress", (int)d->garment_kind);
    WEFT_SEQ_BAD(d->motion_path && d->scenario != WEFT_SIM_SCENARIO_GARMENT,
                 "motion_path is for the garment scenario, not %s", weft_sim_scenario_name(d->scenario));
    WEFT_SEQ_BAD(d->motion_path && (!d->motion_path[0] || strlen(d->motion_path) > 900),
                 "motion_path is empty or longer than 900 characters");
    WEFT_SEQ_BAD(!(d->motion_start_s >= 0.0 && d->motion_start_s <= 1e6), "motion_start_s %g outside [0, 1e6]",
                 d->motion_start_s);
    const weft_sim_character *ch = d->character;
    WEFT_SEQ_BAD(ch && d->scenario != WEFT_SIM_SCENARIO_GARMENT, "character is for the garment scenario, not %s",
                 weft_sim_scenario_name(d->scenario));
    WEFT_SEQ_BAD(ch && d->motion_path, "character and motion_path exclude each other (the character brings its motion)");
    WEFT_SEQ_BAD(ch && (!ch->name || !ch->name[0] || strlen(ch->name) > 64), "character.name must be 1..64 characters");
    WEFT_SEQ_BAD(ch && (!ch->rest_positions || !ch->triangles || ch->vertex_count < 3 || ch->triangle_count == 0),
                 "character needs its bind-pose mesh (rest_positions, triangles)");
    WEFT_SEQ_BAD(ch && (!ch->garment_positions || !ch->garment_triangles || ch->garment_vertex_count < 3 ||
                        ch->garment_triangle_count == 0),
                 "character needs its garment mesh (garment_positions, garment_triangles)");
    WEFT_SEQ_BAD(ch && !ch->collider_at, "character.collider_at is required");
    WEFT_SEQ_BAD(ch && ch->preroll > 1000, "character.preroll %u outside [0, 1000]", ch ? ch->preroll : 0);
    WEFT_SEQ_BAD(d->split && strcmp(d->split, "train") && strcmp(d->split, "val") && strcmp(d->split, "test"),
                 "split '%.32s' is not train, val or test", d->split);
    WEFT_SEQ_BAD(d->checkpoint_frames > 100000, "checkpoint_frames %u outside [0, 100000]", d->checkpoint_frames);
    WEFT_SEQ_BAD(d->prefix_frames_min > 100000, "prefix_frames_min %u outside [0, 100000]", d->prefix_frames_min);
    WEFT_SEQ_BAD(!(d->time_limit_s >= 0.0 && d->time_limit_s <= 1e9), "time_limit_s %g outside [0, 1e9]",
                 d->time_limit_s);
    WEFT_SEQ_BAD(d->time_limit_s > 0.0 && d->checkpoint_frames == 0,
                 "time_limit_s %g needs checkpoint_frames > 0 (a stopped run resumes from a checkpoint)",
                 d->time_limit_s);
#undef WEFT_SEQ_BAD
    return WEFT_OK;
}

weft_result weft_sim_generate(weft_context *ctx, const weft_sim_sequence_def *def, const char *out_dir,
                              weft_sim_progress_fn *progress, void *user, weft_sim_sequence_result *out)
{
    if (!ctx || !def || !out_dir || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_sim_generate: context, def, out_dir and result are required");
    }
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_sim_generate: def was not initialised with weft_sim_default_sequence_def()");
    }
    weft_result bad = check_sequence_def(def, out_dir);
    if (bad != WEFT_OK) {
        return bad;
    }
    xscene sc;
    weft_result r = xscene_build(ctx, &sc, def, def->seed, NULL);
    if (r != WEFT_OK) {
        return r;
    }
    weft_sim_sequence_result res = {0};
    snprintf(res.description, sizeof res.description, "%s", sc.description);
    res.vertex_count = sc.cloth.nv;
    res.collider_vertex_count = sc.collider.nv;
    res.frames = def->frames;
    run_buffers b = {0};
    const size_t T = (size_t)def->frames + sc.preroll, nv = sc.cloth.nv, nc = sc.collider.nv;
    b.cloth = malloc(sizeof(float) * 3 * nv * T);
    b.collider = malloc(sizeof(float) * 3 * nc * T);
    b.pinned = malloc(T * nv);
    b.stats = malloc(sizeof(float) * ST_COUNT * T);
    b.pin_idx = malloc(sizeof(uint32_t) * nv);
    b.pin_tgt = malloc(sizeof(float) * 3 * nv);
    b.path = malloc(sizeof(float) * 3 * nv * ((size_t)def->max_substeps * def->fast_collider_factor + 1));
    ckpt_run ck = {.every = def->checkpoint_frames};
    double *solver_state = def->checkpoint_frames ? malloc(sizeof(double) * 6 * nv) : NULL;
    if (!b.cloth || !b.collider || !b.pinned || !b.stats || !b.pin_idx || !b.pin_tgt || !b.path ||
        (def->checkpoint_frames && !solver_state)) {
        free(solver_state);
        buffers_free(&b);
        xscene_free(&sc);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_sim_generate: out of memory for %zu frames", T);
    }
    /* Retry a rejected sequence with doubled substeps, up to max_substeps. A garment still
     * rejected then gets one more round as a gentler take of the same scene: the arms closing on
     * the chest's sides pinch cloth in a gap thinner than its contact thickness, a motion starting
     * at full speed throws the body into the draped cloth, and the rest of the rejections are
     * runs and jumps at full amplitude (docs/REFSIM.md, Dress rejections). Accepted sequences of
     * the first round never see the second. */
    const xscene_gentle gentle = {def->garment_retry_arm_spread, def->garment_retry_ease_in,
                                  def->garment_retry_amplitude};
    const bool gentle_round = def->scenario == WEFT_SIM_SCENARIO_GARMENT && def->garment_retry && !def->motion_path &&
                              !def->character;
    /* A checkpoint of this def picks the attempt (round, substeps) and the frame to go on from. */
    ckpt_header resume = {0};
    uint32_t round0 = 0, substeps0 = def->substeps;
    if (def->checkpoint_frames) {
        ck.dir = out_dir;
        ck.fingerprint = def_fingerprint(def, (uint32_t)nv, (uint32_t)nc, (uint32_t)T);
        ck.deadline_ms = def->time_limit_s > 0.0 ? weft__now_ms() + 1000.0 * def->time_limit_s : 0.0;
        ck.xd = solver_state;
        ck.vd = solver_state + 3 * nv;
        if (!make_dir(out_dir)) {
            r = weft__fail(WEFT_ERROR_IO, "weft_sim_generate: cannot create '%s'", out_dir);
        } else if (ckpt_read(out_dir, ck.fingerprint, (uint32_t)nv, (uint32_t)nc, (uint32_t)T, &resume, &b, ck.xd,
                             ck.vd) &&
                   (resume.round == 0 || gentle_round)) {
            round0 = resume.round;
            substeps0 = resume.substeps;
            res.attempts = resume.attempts > 0 ? resume.attempts - 1 : 0;
            ck.resume = resume.frame > 0 ? &resume : NULL;
        }
    }
    for (int round = (int)round0; r == WEFT_OK && !res.accepted && !ck.stopped && round < (gentle_round ? 2 : 1);
         ++round) {
        if (round == 1) {
            xscene_free(&sc);
            r = xscene_build(ctx, &sc, def, def->seed, &gentle);
            if (r == WEFT_OK && (sc.cloth.nv != nv || sc.collider.nv != nc || (size_t)def->frames + sc.preroll != T)) {
                xscene_free(&sc);
                r = weft__fail(WEFT_ERROR_SIZE_MISMATCH, "weft_sim_generate: the gentle retry changed the scene's sizes");
            }
            if (r != WEFT_OK) {
                break; /* sc is zeroed: the cleanup below frees nothing twice */
            }
            snprintf(res.description, sizeof res.description, "%s", sc.description);
        }
        for (uint32_t s = round == (int)round0 ? substeps0 : def->substeps; s <= def->max_substeps; s *= 2) {
            res.attempts++;
            res.substeps_used = s;
            res.gentle = round == 1;
            ck.round = (uint32_t)round;
            ck.attempts = res.attempts;
            r = simulate(ctx, &sc, def, s, &b, &res, &ck, progress, user);
            if (r != WEFT_OK || ck.stopped) {
                break;
            }
            res.accepted = res.first_hit_frame < 0;
            inside_summary(&b, res.first_hit_frame < 0 ? T - 1 : (size_t)res.first_hit_frame, &res);
            if (res.accepted || s > def->max_substeps / 2) {
                break;
            }
        }
    }
    res.finished = !ck.stopped;
    /* Real motion: the frames before the rejected one are validated ground truth; a window that
     * recorded enough of them keeps those (docs/DATASET.md, Real-motion acceptance). */
    if (r == WEFT_OK && res.finished && !res.accepted && def->motion_path && def->prefix_frames_min > 0 &&
        res.first_hit_frame > (int32_t)sc.preroll &&
        (uint32_t)res.first_hit_frame - sc.preroll >= def->prefix_frames_min) {
        res.accepted = true;
        res.truncated = true;
        res.frames = (uint32_t)res.first_hit_frame - sc.preroll;
        inside_summary(&b, (size_t)res.first_hit_frame - 1, &res);
    }
    if (r == WEFT_OK && res.finished) {
        if (!make_dir(out_dir)) {
            r = weft__fail(WEFT_ERROR_IO, "weft_sim_generate: cannot create '%s'", out_dir);
        } else if (res.accepted && !write_arrays(out_dir, &sc, &res, &b)) {
            r = weft__fail(WEFT_ERROR_IO, "weft_sim_generate: writing arrays into '%s' failed", out_dir);
        } else if (!write_meta(out_dir, &sc, def, &res)) {
            r = weft__fail(WEFT_ERROR_IO, "weft_sim_generate: writing '%s/meta.json' failed", out_dir);
        }
    }
    if (r == WEFT_OK && res.finished && ck.dir) {
        char path[1100];
        ckpt_path(path, sizeof path, out_dir, "");
        remove(path); /* meta.json marks the sequence finished; the checkpoint has served */
    }
    free(solver_state);
    buffers_free(&b);
    xscene_free(&sc);
    if (r == WEFT_OK) {
        *out = res;
    }
    return r;
}
