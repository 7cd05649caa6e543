/* weft bench lod: the measured level-of-detail table, and the per-character cost of a crowd.
 *
 * 1. Every candidate level (LBS, XPBD at a few substep counts, each model in DIR at fp32/fp16/
 *    int8 with and without CCD, at each collider crop of --crops) runs over the split's sequences, one `weft eval --json` child per
 *    (level, sequence), exactly as `weft bench chart` does. Frame-weighted means go to
 *    <csv-dir>/lod.csv, the file weft_lod_table_load_file() reads (include/weft/lod.h; by default
 *    samples/data, where the samples load it, when <out> is docs, else <out>), and to the
 *    generated sections of <out>/LOD.md.
 * 2. Per-character step cost at 1, 8 and 64 characters: N default avatars walking, each wearing
 *    a T-shirt driven by a weft_lod_garment at one level of the table just written, stepped in
 *    one thread. Pose and collider upload are outside the timed region.
 *
 * LOD.md keeps its hand-written text: only the blocks between "<!-- lod:table -->" /
 * "<!-- lod:scaling -->" and their "<!-- /lod:... -->" end markers are replaced. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include "weft.h"
#include "weft/body.h"
#include "weft/lod.h"
#include "support_bench.h"
#include "support_cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

const char weft_bench_lod_help[] =
    "level-of-detail table: ms/frame and MVE per level (samples/data/lod.csv + docs/LOD.md), crowd cost at 1/8/64";

/* Where the tables the samples load live (avatar_render --crowd: samples/common/crowd.c). */
#define LOD_TABLE_DIR "samples/data"

#define LOD_MAX_CANDS 160
#define LOD_MAX_SCALE 16
#define LOD_MAX_CROPS 8
#define LOD_MAX_SIM 4

/* One collider crop to measure model levels at (weft_garment_def.collider_crop_*). */
typedef struct lod_crop {
    double cm;                  /* 0: the model's own margin */
    bool cells;                 /* WEFT_COLLIDER_CROP_CELLS, else BOX */
    uint32_t tokens;            /* max_collider_tokens, 0: no cap */
} lod_crop;

typedef struct lod_cand {
    char name[WEFT_LOD_NAME_CAP];
    char method[16];            /* --method value for eval: lbs, xpbd:S, model */
    const char *family;         /* lbs, xpbd, model */
    char model_name[WEFT_LOD_NAME_CAP]; /* metadata name */
    char model_file[1024];
    char precision[8];
    unsigned substeps;
    bool ccd;
    lod_crop crop;              /* model levels only */
    double tether_cm, strain_pct; /* 0: none */
    double push_cm;             /* 0: no collider push */
    int sim;                    /* resolution level: 0 the sequence's own mesh, i + 1 lod_opts.sim_data[i] */
    uint32_t sequences, frames, failed, nan_runs;
    double mve_w, ms_w, strain;
    char note[240];
} lod_cand;

typedef struct lod_opts {
    const char *data, *split, *models, *out, *scale_levels, *scale_res;
    const char *csv_dir;                /* where NAME.csv goes (bench_csv_dir: samples/data when OUT is docs) */
    const char *scenario;               /* only sequences of this scenario; NULL: all */
    const char *name;                   /* CSVDIR/<name>.csv, and its own blocks in OUT/LOD.md unless "lod" */
    double tether_cm, strain_pct;       /* > 0: also measure the deployed garment levels with these */
    double push_cm;                     /* > 0: ... and with the collider push */
    uint32_t frames, max_seqs, scale_frames;
    unsigned xpbd[8];
    size_t nxpbd;
    lod_crop crops[LOD_MAX_CROPS];
    size_t ncrops;
    const char *cost_model;             /* --crop-cost: the model file */
    /* --sim-data: folders of coarser meshes of the split's garments (resolution levels); per folder
     * the coarse sequence folder of each sequence ("" when none) and the mean vertex share. */
    const char *sim_data[LOD_MAX_SIM];
    size_t nsim;
    char (*sim_dir)[1024];              /* [nsim][nseq] */
    double sim_res[LOD_MAX_SIM];
    bool scale, scale_only, crop_cost;
} lod_opts;

#define LOD_STR_(x) #x
#define LOD_STR(x) LOD_STR_(x)

enum {
    OPT_DATA = 1, OPT_SPLIT, OPT_MODELS, OPT_OUT, OPT_CSV_DIR, OPT_FRAMES, OPT_MAX_SEQS, OPT_XPBD, OPT_NO_SCALE,
    OPT_SCALE_LEVELS, OPT_SCALE_FRAMES, OPT_SCALE_RES, OPT_SCALE_ONLY, OPT_CROPS, OPT_CROP_COST, OPT_CROP_MODEL,
    OPT_SCENARIO, OPT_NAME, OPT_TETHER_CM, OPT_STRAIN_LIMIT, OPT_PUSH_CM, OPT_SIM_DATA,
};

static const cli_option k_options[] = {
    {"data", "DIR", OPT_DATA, "the simgen data folder (required, except with --scale-only or --crop-cost)"},
    {"split", "test|val|train|all", OPT_SPLIT, "the split measured (default test)"},
    {"models", "DIR", OPT_MODELS, "the models measured, DIR/*.safetensors (default tools/train/models)"},
    {"out", "DIR", OPT_OUT, "where LOD.md is (default docs)"},
    {"csv-dir", "DIR", OPT_CSV_DIR,
     "where the table goes (default: samples/data, where the samples load it,\n"
     "when OUT is docs; else OUT)"},
    {"frames", "N", OPT_FRAMES, "frames of each sequence, 0..1000000 (0: whole sequences)"},
    {"max-seqs", "N", OPT_MAX_SEQS,
     "at most N sequences of each scenario (the first by name), as bench\n"
     "chart; 0..1000000 (0: every sequence)"},
    {"xpbd", "5,10,20", OPT_XPBD, "up to 8 substep counts, each 1..1000 (default 5,10,20)"},
    {"no-scale", NULL, OPT_NO_SCALE, "skip the per-character step cost"},
    {"scale-levels", "a,b,...", OPT_SCALE_LEVELS,
     "the levels of the per-character step cost (default: lbs, xpbd-5, every\n"
     "model at int8 and fp32 with CCD and at fp32 without)"},
    {"scale-frames", "N", OPT_SCALE_FRAMES, "timed frames of the per-character step cost, 1..1000000 (default 4)"},
    {"scale-res", "1k|4k|16k|40k", OPT_SCALE_RES, "the T-shirt of the per-character step cost (default 1k)"},
    {"scale-only", NULL, OPT_SCALE_ONLY,
     "skip the table: reuse CSVDIR/lod.csv and regenerate only the\n"
     "per-character section"},
    {"crops", "L", OPT_CROPS,
     "collider crops to measure every model level at (default: model, the\n"
     "model's own): 'model' or a margin in cm (box rule, as trained),\n"
     "optionally :cells (finer rule) and @N (keep at most N triangles, the\n"
     "nearest), e.g. model,8,8:cells,model@3000; at most " LOD_STR(LOD_MAX_CROPS) ". Levels are\n"
     "named <model>-<precision>[-noccd][-cropCM|-cellsCM|-cells][-capN]"},
    {"crop-cost", NULL, OPT_CROP_COST,
     "only measure the step cost of the --crops on the walking default avatar\n"
     "(T-shirt --scale-res, --scale-frames timed frames, CCD off, fp32): one\n"
     "garment per crop, stepped in turn each frame; prints median and min ms\n"
     "per step and the mean kept tokens"},
    {"crop-model", "FILE", OPT_CROP_MODEL, "the model of --crop-cost (default MODELS/game.safetensors)"},
    {"scenario", "S", OPT_SCENARIO, "only the split's sequences of scenario S (e.g. garment)"},
    {"name", "NAME", OPT_NAME,
     "write CSVDIR/NAME.csv and the tables into their own sections of\n"
     "OUT/LOD.md ([a-z0-9_-], at most 40 characters; default lod)"},
    {"tether-cm", "X", OPT_TETHER_CM,
     "also measure LBS, the first XPBD and every model's int8 (CCD on and off)\n"
     "with tethers of X cm, 0.01..1000 (levels named ...-tX-sP)"},
    {"strain-limit", "P", OPT_STRAIN_LIMIT, "... and/or with a P % strain limit, 0.01..1000"},
    {"push-cm", "X", OPT_PUSH_CM,
     "... and/or the collider push at X cm, 0.01..10 (levels named ...-pX;\n"
     "docs/CCD.md)"},
    {"sim-data", "DIR", OPT_SIM_DATA,
     "resolution levels: each sequence is also simulated on its coarser mesh\n"
     "in DIR (the sequence of the same scenario and index there,\n"
     "`weft simgen --resolution-series`) and scored on its own mesh\n"
     "(weft eval --sim-mesh) for LBS, the first XPBD and every model at its\n"
     "own crop; the level's resolution is the vertex share (named -rSHARE).\n"
     "Up to " LOD_STR(LOD_MAX_SIM) " times."},
    {0},
};

static const cli_command k_command = {
    .tool = "weft bench lod",
    .synopsis = "weft bench lod --data DIR [--split test|val|train|all] [--models DIR] [--out DIR]\n"
                "               [--csv-dir DIR] [--frames N] [--max-seqs N] [--xpbd 5,10,20] [--no-scale]\n"
                "               [--scale-levels a,b,...] [--scale-frames N] [--scale-res RES] [--scale-only]\n"
                "               [--crops model,8,4:cells] [--scenario S] [--name NAME] [--tether-cm X]\n"
                "               [--strain-limit P] [--push-cm X] [--sim-data DIR]...\n"
                "               [--crop-cost [--crop-model FILE]]",
    .about = "Measures every level (LBS, XPBD at the given substeps, each DIR/*.safetensors model at\n"
             "fp32/fp16/int8 with and without CCD) on the split through `weft eval --json`, writes CSVDIR/lod.csv\n"
             "(loadable by weft_lod_table_load_file) and the table in OUT/LOD.md, then measures the\n"
             "per-character step cost of 1, 8 and 64 walking avatars at the --scale-levels. Default OUT: docs.",
    .options = k_options,
};

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static bool cand_valid(const lod_cand *c)
{
    return c->frames > 0 && c->nan_runs == 0 && c->failed == 0 && isfinite(c->mve_w / c->frames) &&
           c->ms_w / c->frames > 0.0;
}

/* Metadata "name" of a model file, for the table's model column. */
static bool model_meta_name(weft_context *ctx, const char *file, char *out, size_t cap)
{
    weft_model *m = NULL;
    if (weft_model_load_file(ctx, file, &m) != WEFT_OK) {
        return false;
    }
    weft_model_info info = weft_model_get_info(m);
    bool ok = info.name && info.name[0] && strlen(info.name) < cap;
    if (ok) {
        snprintf(out, cap, "%s", info.name);
        for (char *p = out; *p; ++p) { /* the table's name alphabet */
            bool good = (*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') ||
                        *p == '_' || *p == '.' || *p == '-';
            ok = ok && good;
        }
    }
    weft_model_destroy(m);
    return ok;
}

/* ---------------------------------------------------------------------------------------- */
/* Part 1: the table                                                                          */

/* "model,8,4:cells,model@3000" into crops; 0 on a malformed list (bad number, duplicate, too
 * many). */
static size_t parse_crops(const char *list, lod_crop *out, size_t cap)
{
    size_t n = 0;
    const char *p = list;
    while (*p) {
        const char *e = strchr(p, ',');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        char item[32];
        if (len == 0 || len >= sizeof item || n == cap) {
            return 0;
        }
        memcpy(item, p, len);
        item[len] = '\0';
        lod_crop c = {0.0, false, 0};
        char *at = strchr(item, '@');
        if (at) {
            char *end;
            unsigned long v = strtoul(at + 1, &end, 10);
            if (*end || end == at + 1 || at[1] == '-' || v == 0 || v > 100000000ul) {
                return 0;
            }
            c.tokens = (uint32_t)v;
            *at = '\0';
        }
        char *colon = strchr(item, ':');
        if (colon) {
            if (strcmp(colon + 1, "cells") != 0 && strcmp(colon + 1, "box") != 0) {
                return 0;
            }
            c.cells = strcmp(colon + 1, "cells") == 0;
            *colon = '\0';
        }
        if (strcmp(item, "model") != 0) {
            char *end;
            c.cm = strtod(item, &end);
            if (*end || end == item || !(c.cm > 0.0) || c.cm > 10000.0) {
                return 0;
            }
        }
        for (size_t i = 0; i < n; ++i) {
            if (out[i].cm == c.cm && out[i].cells == c.cells && out[i].tokens == c.tokens) {
                return 0;
            }
        }
        out[n++] = c;
        p = e ? e + 1 : p + len;
        if (e && !*p) {
            return 0; /* trailing comma */
        }
    }
    return n;
}

static size_t build_candidates(weft_context *ctx, const lod_opts *o, lod_cand *c, char skipped[][300], size_t *nskip)
{
    size_t n = 0;
    for (int ccd = 1; ccd >= 0; --ccd) {
        lod_cand *k = &c[n++];
        memset(k, 0, sizeof *k);
        snprintf(k->name, sizeof k->name, "lbs%s", ccd ? "" : "-noccd");
        snprintf(k->method, sizeof k->method, "lbs");
        k->family = "lbs";
        k->ccd = ccd != 0;
    }
    for (size_t i = 0; i < o->nxpbd; ++i) {
        lod_cand *k = &c[n++];
        memset(k, 0, sizeof *k);
        snprintf(k->name, sizeof k->name, "xpbd-%u", o->xpbd[i]);
        snprintf(k->method, sizeof k->method, "xpbd:%u", o->xpbd[i]);
        k->family = "xpbd";
        k->substeps = o->xpbd[i];
        k->ccd = true;
    }
    static char files[32][256];
    size_t nf = bench_list_models(o->models, files, 32);
    if (nf == 0) {
        snprintf(skipped[(*nskip)++], 300, "learned models: no `*.safetensors` under `%s`", o->models);
    }
    static const char *const precs[] = {"fp32", "fp16", "int8"};
    for (size_t i = 0; i < nf && n + 6 * o->ncrops <= LOD_MAX_CANDS; ++i) {
        char stem[256], base[1300], meta[WEFT_LOD_NAME_CAP];
        snprintf(stem, sizeof stem, "%s", files[i]);
        stem[strlen(stem) - 12] = '\0';
        snprintf(base, sizeof base, "%s/%s", o->models, files[i]);
        if (!model_meta_name(ctx, base, meta, sizeof meta)) {
            snprintf(skipped[(*nskip)++], 300, "model `%.150s`: not loadable or no usable metadata name (%.60s)", base,
                     weft_last_error());
            continue;
        }
        for (size_t q = 0; q < o->ncrops; ++q) {
            const lod_crop *cr = &o->crops[q];
            char suffix[40] = "";
            if (cr->cm > 0.0 || cr->cells) {
                snprintf(suffix, sizeof suffix, "-%s%.4g", cr->cells ? "cells" : "crop", cr->cm);
                if (cr->cm == 0.0) {
                    suffix[strlen(suffix) - 1] = '\0'; /* "-cells": the model's margin */
                }
            }
            if (cr->tokens) {
                const size_t used = strlen(suffix);
                snprintf(suffix + used, sizeof suffix - used, "-cap%u", cr->tokens);
            }
            /* The longest name of this crop ("-fp32-noccd" is the longest middle) must fit. */
            char full[160];
            snprintf(full, sizeof full, "%.30s-fp32-noccd%s", meta, suffix);
            if (strlen(full) >= WEFT_LOD_NAME_CAP) {
                if (*nskip < 16) {
                    snprintf(skipped[(*nskip)++], 300, "crop `%.40s` of model `%.40s`: level name over %u characters",
                             suffix + 1, meta, WEFT_LOD_NAME_CAP - 1);
                }
                continue;
            }
            for (int p = 0; p < 3; ++p) {
                for (int ccd = 1; ccd >= 0; --ccd) {
                    lod_cand *k = &c[n++];
                    memset(k, 0, sizeof *k);
                    snprintf(full, sizeof full, "%.30s-%s%s%s", meta, precs[p], ccd ? "" : "-noccd", suffix);
                    memcpy(k->name, full, strlen(full) + 1); /* fits: checked above */
                    k->crop = *cr;
                    snprintf(k->method, sizeof k->method, "model");
                    k->family = "model";
                    snprintf(k->model_name, sizeof k->model_name, "%s", meta);
                    snprintf(k->precision, sizeof k->precision, "%s", precs[p]);
                    bench_model_file(o->models, stem, files[i], precs[p], k->model_file, sizeof k->model_file);
                    k->ccd = ccd != 0;
                }
            }
        }
    }
    /* The deployed garment levels: the same methods with tethers and/or the strain limit. */
    if (o->tether_cm > 0.0 || o->strain_pct > 0.0 || o->push_cm > 0.0) {
        char suffix[48] = "";
        if (o->tether_cm > 0.0) {
            snprintf(suffix, sizeof suffix, "-t%.4g", o->tether_cm);
        }
        if (o->strain_pct > 0.0) {
            size_t used = strlen(suffix);
            snprintf(suffix + used, sizeof suffix - used, "-s%.4g", o->strain_pct);
        }
        if (o->push_cm > 0.0) {
            size_t used = strlen(suffix);
            snprintf(suffix + used, sizeof suffix - used, "-p%.4g", o->push_cm);
        }
        const size_t base = n;
        for (size_t i = 0; i < base && n < LOD_MAX_CANDS; ++i) {
            const lod_cand *b = &c[i];
            bool first_xpbd = strcmp(b->family, "xpbd") == 0 && o->nxpbd && b->substeps == o->xpbd[0];
            bool int8_own = strcmp(b->family, "model") == 0 && strcmp(b->precision, "int8") == 0 &&
                            b->crop.cm == 0.0 && !b->crop.cells && !b->crop.tokens;
            if (!(strcmp(b->family, "lbs") == 0 || first_xpbd || int8_own)) {
                continue;
            }
            char full[160];
            snprintf(full, sizeof full, "%.47s%.31s", b->name, suffix);
            if (strlen(full) >= WEFT_LOD_NAME_CAP) {
                continue;
            }
            c[n] = *b;
            memcpy(c[n].name, full, strlen(full) + 1);
            c[n].tether_cm = o->tether_cm;
            c[n].strain_pct = o->strain_pct;
            c[n].push_cm = o->push_cm;
            n++;
        }
    }
    /* Resolution levels: LBS, the first XPBD and every model at its own crop, simulated on the
     * coarser mesh of each --sim-data folder (garment levels with tethers stay at full resolution). */
    const size_t base = n;
    for (size_t i = 0; i < o->nsim; ++i) {
        for (size_t j = 0; j < base && n < LOD_MAX_CANDS; ++j) {
            const lod_cand *b = &c[j];
            bool first_xpbd = strcmp(b->family, "xpbd") == 0 && o->nxpbd && b->substeps == o->xpbd[0];
            bool model_own = strcmp(b->family, "model") == 0 && b->crop.cm == 0.0 && !b->crop.cells && !b->crop.tokens;
            if (b->sim || b->tether_cm > 0.0 || b->strain_pct > 0.0 || b->push_cm > 0.0 ||
                !(strcmp(b->family, "lbs") == 0 || first_xpbd || model_own)) {
                continue;
            }
            char full[160];
            snprintf(full, sizeof full, "%.47s-r%.2f", b->name, o->sim_res[i]);
            if (strlen(full) >= WEFT_LOD_NAME_CAP) {
                continue;
            }
            c[n] = *b;
            memcpy(c[n].name, full, strlen(full) + 1);
            c[n].sim = (int)i + 1;
            n++;
        }
    }
    return n;
}

/* Pairs each sequence with its coarser mesh in every --sim-data folder: the sequence of the same
 * scenario and index (the number after the last '_', as `weft simgen --resolution-series` names
 * them) with fewer vertices. Fills o->sim_dir and o->sim_res; false (with a message) when a
 * folder cannot be read or pairs with no sequence. */
static bool pair_sim_meshes(lod_opts *o, const bench_seq *seqs, size_t nseq)
{
    o->sim_dir = calloc(o->nsim * (nseq ? nseq : 1), sizeof *o->sim_dir);
    if (!o->sim_dir) {
        fprintf(stderr, "weft bench lod: out of memory\n");
        return false;
    }
    for (size_t i = 0; i < o->nsim; ++i) {
        bench_seq *cs = NULL;
        size_t ncs = 0;
        if (!bench_list_sequences(o->sim_data[i], NULL, &cs, &ncs) || ncs == 0) {
            fprintf(stderr, "weft bench lod: --sim-data %s: no sequences there\n", o->sim_data[i]);
            free(cs);
            return false;
        }
        double share = 0.0;
        size_t paired = 0;
        for (size_t s = 0; s < nseq; ++s) {
            const char *idx = strrchr(seqs[s].name, '_');
            for (size_t j = 0; idx && j < ncs; ++j) {
                const char *cidx = strrchr(cs[j].name, '_');
                if (cidx && strcmp(cidx, idx) == 0 && strcmp(cs[j].scenario, seqs[s].scenario) == 0 &&
                    cs[j].vertices > 0 && cs[j].vertices < seqs[s].vertices) {
                    snprintf(o->sim_dir[i * nseq + s], sizeof o->sim_dir[0], "%s", cs[j].dir);
                    share += (double)cs[j].vertices / seqs[s].vertices;
                    paired++;
                    break;
                }
            }
        }
        free(cs);
        if (paired == 0) {
            fprintf(stderr,
                    "weft bench lod: --sim-data %s: no coarser mesh of any measured sequence (same scenario and "
                    "index, fewer vertices)\n",
                    o->sim_data[i]);
            return false;
        }
        o->sim_res[i] = share / (double)paired;
        printf("resolution level %zu: %zu of %zu sequences paired with a coarser mesh under %s, mean vertex share "
               "%.3f\n",
               i + 1, paired, nseq, o->sim_data[i], o->sim_res[i]);
    }
    return true;
}

static void run_candidates(const char *exe, const lod_opts *o, const bench_seq *seqs, size_t nseq, lod_cand *c,
                           size_t nc)
{
    char frames_arg[16];
    snprintf(frames_arg, sizeof frames_arg, "%u", o->frames);
    for (size_t k = 0; k < nc; ++k) {
        char crop_arg[32], tokens_arg[16], tether_arg[32], strain_arg[32], push_arg[32];
        snprintf(tether_arg, sizeof tether_arg, "%.9g", c[k].tether_cm);
        snprintf(strain_arg, sizeof strain_arg, "%.9g", c[k].strain_pct);
        snprintf(push_arg, sizeof push_arg, "%.9g", c[k].push_cm);
        snprintf(crop_arg, sizeof crop_arg, "%.9g", c[k].crop.cm);
        snprintf(tokens_arg, sizeof tokens_arg, "%u", c[k].crop.tokens);
        for (size_t s = 0; s < nseq; ++s) {
            const char *extra[32];
            int n = 0;
            extra[n++] = "--method";
            extra[n++] = c[k].method;
            extra[n++] = "--ccd";
            extra[n++] = c[k].ccd ? "on" : "off";
            if (o->frames) {
                extra[n++] = "--frames";
                extra[n++] = frames_arg;
            }
            if (strcmp(c[k].family, "model") == 0) {
                extra[n++] = "--model";
                extra[n++] = c[k].model_file;
                extra[n++] = "--precision";
                extra[n++] = c[k].precision;
                if (c[k].crop.cm > 0.0) {
                    extra[n++] = "--crop-cm";
                    extra[n++] = crop_arg;
                }
                if (c[k].crop.cells) {
                    extra[n++] = "--crop";
                    extra[n++] = "cells";
                }
                if (c[k].crop.tokens) {
                    extra[n++] = "--max-collider-tokens";
                    extra[n++] = tokens_arg;
                }
            }
            if (c[k].tether_cm > 0.0) {
                extra[n++] = "--tether-cm";
                extra[n++] = tether_arg;
            }
            if (c[k].strain_pct > 0.0) {
                extra[n++] = "--strain-limit";
                extra[n++] = strain_arg;
            }
            if (c[k].push_cm > 0.0) {
                extra[n++] = "--push-cm";
                extra[n++] = push_arg;
            }
            if (strcmp(c[k].family, "xpbd") != 0) { /* the scene's pins for every method (bench_method_args) */
                extra[n++] = "--pins";
                extra[n++] = "all";
            }
            const char *sim = c[k].sim ? o->sim_dir[(size_t)(c[k].sim - 1) * nseq + s] : NULL;
            if (sim) {
                extra[n++] = "--sim-mesh";
                extra[n++] = sim;
            }
            extra[n] = NULL;
            bench_eval_result e;
            if (sim && !sim[0]) { /* this sequence has no coarser twin: the level fails on it */
                memset(&e, 0, sizeof e);
                snprintf(e.why, sizeof e.why, "no coarser mesh of %.60s under %.100s", seqs[s].name,
                         o->sim_data[c[k].sim - 1]);
            } else {
                bench_eval(exe, seqs[s].dir, extra, &e);
            }
            c[k].sequences++;
            if (!e.ok) {
                c[k].failed++;
                if (!c[k].note[0]) {
                    snprintf(c[k].note, sizeof c[k].note, "%s", e.why);
                }
                printf("%-24s %-22s FAILED: %s\n", seqs[s].name, c[k].name, e.why);
                continue;
            }
            c[k].frames += e.frames;
            c[k].mve_w += e.mve_cm * e.frames;
            c[k].ms_w += e.ms_per_frame * e.frames;
            c[k].strain = fmax(c[k].strain, e.max_edge_strain);
            c[k].nan_runs += e.nan;
            printf("%-24s %-22s frames %4u  MVE %8.3f cm  %9.3f ms/frame%s\n", seqs[s].name, c[k].name, e.frames,
                   e.mve_cm, e.ms_per_frame, e.nan ? "  NaN" : "");
            fflush(stdout);
        }
    }
}

static bool write_csv(const char *path, const lod_cand *c, size_t nc, const char *command, const lod_opts *o)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "weft bench lod: cannot write %s\n", path);
        return false;
    }
    fprintf(f, "# weft level-of-detail table, measured by: %s\n", command);
    fprintf(f, "# data %s, split %s%s%s; build and machine: %s\n", o->data, o->split, o->scenario ? ", scenario " : "",
            o->scenario ? o->scenario : "", weft_config_string());
    fprintf(f, "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,"
               "frames,crop_cm,collider_crop,max_collider_tokens,tether_cm,strain_limit_pct,push_cm\n");
    for (size_t k = 0; k < nc; ++k) {
        if (!cand_valid(&c[k])) {
            continue;
        }
        char sub[16] = "-";
        if (c[k].substeps) {
            snprintf(sub, sizeof sub, "%u", c[k].substeps);
        }
        bool model = strcmp(c[k].family, "model") == 0;
        char crop_cm[32] = "-", tokens[16] = "-";
        if (model && c[k].crop.cm > 0.0) {
            snprintf(crop_cm, sizeof crop_cm, "%.9g", c[k].crop.cm);
        }
        if (model && c[k].crop.tokens) {
            snprintf(tokens, sizeof tokens, "%u", c[k].crop.tokens);
        }
        char tether[32] = "-", strain[32] = "-";
        if (c[k].tether_cm > 0.0) {
            snprintf(tether, sizeof tether, "%.9g", c[k].tether_cm);
        }
        if (c[k].strain_pct > 0.0) {
            snprintf(strain, sizeof strain, "%.9g", c[k].strain_pct);
        }
        char push[32] = "-";
        if (c[k].push_cm > 0.0) {
            snprintf(push, sizeof push, "%.9g", c[k].push_cm);
        }
        fprintf(f, "%s,%s,%s,%s,%s,%s,%.3g,%.6g,%.6g,%.6g,%u,%u,%s,%s,%s,%s,%s,%s\n", c[k].name, c[k].family,
                model ? c[k].model_name : "-", model ? c[k].precision : "-", sub, c[k].ccd ? "on" : "off",
                c[k].sim ? o->sim_res[c[k].sim - 1] : 1.0, c[k].ms_w / c[k].frames, c[k].mve_w / c[k].frames, c[k].strain, c[k].sequences, c[k].frames, crop_cm,
                model ? (c[k].crop.cells ? "cells" : "box") : "-", tokens, tether, strain, push);
    }
    fclose(f);
    return true;
}

/* ---------------------------------------------------------------------------------------- */
/* Part 2: per-character cost                                                                 */

typedef struct scale_row {
    char level[WEFT_LOD_NAME_CAP];
    uint32_t n;
    bool batched;                       /* weft_garments_step over all characters, else one by one */
    double ms_per_char, ms_total;
    char note[160];
} scale_row;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Steps n avatars at one level for `frames` timed frames after `lead` untimed ones; median ms. */
static bool scale_one(weft_context *ctx, const weft_body *body, const weft_cloth_mesh *cloth, const weft_lod_table *t,
                      uint32_t level, const weft_model *const *models, uint32_t nmodels, uint32_t n, uint32_t frames,
                      scale_row *row)
{
    const uint32_t nb = weft_body_vertex_count(body);
    weft_lod_garment **g = calloc(n, sizeof *g);
    weft_garment **cur = calloc(n, sizeof *cur);
    float *verts = malloc((size_t)nb * 3 * sizeof(float));
    float *placed = malloc((size_t)nb * 3 * sizeof(float));
    float *rest = malloc((size_t)cloth->vertex_count * 3 * sizeof(float));
    bool ok = g && cur && verts && placed && rest;
    weft_motion_def md = weft_default_motion_def(WEFT_MOTION_WALK);
    /* Per-frame totals; the median is reported, as the machine these run on is shared and a
     * mean is dragged by frames where another process held the core. */
    double *frame_ms = calloc(frames, sizeof *frame_ms);
    ok = ok && frame_ms;
    for (uint32_t i = 0; ok && i < n; ++i) {
        /* Characters 1.2 m apart along X; the garment is created on the bind pose there. */
        const float dx = 1.2f * (float)i;
        const float *br = weft_body_rest_vertices(body);
        for (uint32_t v = 0; v < nb; ++v) {
            placed[3 * v] = br[3 * v] + dx;
            placed[3 * v + 1] = br[3 * v + 1];
            placed[3 * v + 2] = br[3 * v + 2];
        }
        for (uint32_t v = 0; v < cloth->vertex_count; ++v) {
            rest[3 * v] = cloth->positions[3 * v] + dx;
            rest[3 * v + 1] = cloth->positions[3 * v + 1];
            rest[3 * v + 2] = cloth->positions[3 * v + 2];
        }
        weft_lod_garment_def d = weft_default_lod_garment_def();
        d.table = t;
        d.level = level;
        d.models = models;
        d.model_count = nmodels;
        d.rest_positions = rest;
        d.vertex_count = cloth->vertex_count;
        d.triangles = cloth->triangles;
        d.triangle_count = cloth->triangle_count;
        d.collider_rest_positions = placed;
        d.collider_vertex_count = nb;
        d.collider_triangles = weft_body_triangles(body);
        d.collider_triangle_count = weft_body_triangle_count(body);
        if (weft_lod_garment_create(ctx, &d, &g[i]) != WEFT_OK) {
            snprintf(row->note, sizeof row->note, "%s", weft_last_error());
            ok = false;
        }
    }
    /* The walk starts from the bind pose: blend in over the first frames so XPBD is not asked to
     * resolve a teleporting body (the blend frames are untimed). */
    const uint32_t lead = 4;
    for (uint32_t f = 0; ok && f < lead + frames; ++f) {
        for (uint32_t i = 0; ok && i < n; ++i) {
            weft_pose pose, bind;
            double tt = (double)f / 60.0 + 0.05 * i;
            ok = weft_motion_sample(&md, tt, &pose) == WEFT_OK;
            if (ok && f < lead) {
                weft_body_bind_pose(body, &bind);
                float u = (float)(f + 1) / (float)lead;
                for (int j = 0; j < 3 * WEFT_BODY_JOINTS; ++j) {
                    pose.rotations[j] = bind.rotations[j] + u * (pose.rotations[j] - bind.rotations[j]);
                }
            }
            pose.translation[0] = 1.2f * (float)i;
            pose.translation[2] = 0.0f;
            ok = ok && weft_body_pose(body, &pose, verts, NULL) == WEFT_OK &&
                 weft_lod_garment_set_collider(g[i], verts) == WEFT_OK;
        }
        double t0 = now_s();
        if (ok && row->batched) {
            /* set_collider has recorded each garment's frame, so stepping the current garments
             * directly keeps the LOD state complete. */
            for (uint32_t i = 0; i < n; ++i) {
                cur[i] = weft_lod_garment_current(g[i]);
            }
            ok = weft_garments_step(cur, n) == WEFT_OK;
        }
        for (uint32_t i = 0; ok && !row->batched && i < n; ++i) {
            ok = weft_lod_garment_step(g[i]) == WEFT_OK;
        }
        if (!ok && !row->note[0]) {
            snprintf(row->note, sizeof row->note, "%s", weft_last_error());
        }
        if (f >= lead) {
            frame_ms[f - lead] = (now_s() - t0) * 1e3;
        }
    }
    for (uint32_t i = 0; g && i < n; ++i) {
        weft_lod_garment_destroy(g[i]);
    }
    free(g);
    free(cur);
    free(verts);
    free(placed);
    free(rest);
    row->n = n;
    if (ok) {
        qsort(frame_ms, frames, sizeof *frame_ms, cmp_double);
        row->ms_total = frames % 2 ? frame_ms[frames / 2] : 0.5 * (frame_ms[frames / 2 - 1] + frame_ms[frames / 2]);
    } else {
        row->ms_total = NAN;
    }
    free(frame_ms);
    row->ms_per_char = ok ? row->ms_total / n : NAN;
    return ok;
}

static size_t run_scaling(const lod_opts *o, const char *csv, scale_row *rows, size_t cap, char *desc, size_t desc_cap)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_body *body = NULL;
    weft_cloth_mesh *cloth = NULL;
    weft_lod_table *t = NULL;
    weft_model *models[32] = {NULL};
    uint32_t nmodels = 0;
    size_t nrows = 0;
    weft_avatar_def ad = weft_default_avatar_def();
    weft_cloth_def cl = weft_default_cloth_def(WEFT_CLOTH_TSHIRT);
    bool ok = weft_context_create(&cd, &ctx) == WEFT_OK && weft_avatar_create(ctx, &ad, &body) == WEFT_OK &&
              weft_cloth_resolution_from_name(o->scale_res, &cl.resolution) == WEFT_OK &&
              weft_cloth_create(ctx, &cl, body, &cloth) == WEFT_OK && weft_lod_table_load_file(ctx, csv, &t) == WEFT_OK;
    if (!ok) {
        fprintf(stderr, "weft bench lod: scaling setup: %s\n", weft_last_error());
    }
    static char files[32][256];
    size_t nf = ok ? bench_list_models(o->models, files, 32) : 0;
    for (size_t i = 0; i < nf; ++i) {
        char path[1300];
        snprintf(path, sizeof path, "%s/%s", o->models, files[i]);
        if (weft_model_load_file(ctx, path, &models[nmodels]) == WEFT_OK) {
            nmodels++;
        }
    }
    if (ok) {
        snprintf(desc, desc_cap, "default avatar (%u vertices, %u triangles) walking, T-shirt %s (%u vertices)",
                 weft_body_vertex_count(body), weft_body_triangle_count(body), o->scale_res, cloth->vertex_count);
    }
    /* Levels: the list given, else lbs, xpbd-5 and each model's int8 and fp32 with CCD. */
    char list[1024];
    if (o->scale_levels) {
        snprintf(list, sizeof list, "%s", o->scale_levels);
    } else {
        list[0] = '\0';
        for (uint32_t i = 0; ok && i < weft_lod_table_count(t); ++i) {
            const weft_lod_level *l = weft_lod_table_level(t, i);
            /* fp32 without CCD shows the model step alone, where batching can matter. */
            /* Crop variants only when asked for by name: 64 avatars per level are slow. */
            bool want = strcmp(l->name, "lbs") == 0 || strcmp(l->name, "xpbd-5") == 0 ||
                        (l->method == WEFT_METHOD_MODEL && l->precision != WEFT_PRECISION_FP16 &&
                         (l->ccd || l->precision == WEFT_PRECISION_FP32) && l->crop_cm == 0.0 &&
                         l->collider_crop == WEFT_COLLIDER_CROP_BOX && l->max_collider_tokens == 0);
            if (want) {
                size_t len = strlen(list);
                snprintf(list + len, sizeof list - len, "%s%s", len ? "," : "", l->name);
            }
        }
    }
    static const uint32_t counts[] = {1, 8, 64};
    for (char *p = list; ok && *p;) {
        char *comma = strchr(p, ',');
        char name[WEFT_LOD_NAME_CAP];
        size_t len = comma ? (size_t)(comma - p) : strlen(p);
        snprintf(name, sizeof name, "%.*s", (int)(len < WEFT_LOD_NAME_CAP - 1 ? len : WEFT_LOD_NAME_CAP - 1), p);
        p = comma ? comma + 1 : p + len;
        uint32_t level = 0;
        if (weft_lod_table_find(t, name, &level) != WEFT_OK) {
            fprintf(stderr, "weft bench lod: --scale-levels: %s (not in the measured table)\n", name);
            continue;
        }
        /* Only model levels differ when batched: weft_garments_step steps other methods one by one. */
        const weft_lod_level *lv = weft_lod_table_level(t, level);
        for (int batched = 0; batched < (lv->method == WEFT_METHOD_MODEL ? 2 : 1); ++batched) {
            for (size_t c = 0; c < sizeof counts / sizeof counts[0] && nrows < cap; ++c) {
                scale_row *r = &rows[nrows++];
                memset(r, 0, sizeof *r);
                snprintf(r->level, sizeof r->level, "%s", name);
                r->batched = batched != 0;
                scale_one(ctx, body, cloth, t, level, (const weft_model *const *)models, nmodels, counts[c],
                          o->scale_frames, r);
                printf("scaling %-22s x%-3u %-10s %9.3f ms/character  %10.3f ms/frame total%s%s\n", name, counts[c],
                       batched ? "batched" : "sequential", r->ms_per_char, r->ms_total, r->note[0] ? "  " : "",
                       r->note);
                fflush(stdout);
            }
        }
    }
    for (uint32_t i = 0; i < nmodels; ++i) {
        weft_model_destroy(models[i]);
    }
    weft_lod_table_destroy(t);
    weft_cloth_destroy(cloth);
    weft_body_destroy(body);
    if (ctx) {
        weft_context_destroy(ctx);
    }
    return nrows;
}

/* ---------------------------------------------------------------------------------------- */
/* --crop-cost: what each crop costs per step on the avatar                                   */

/* One garment per crop on one walking avatar, stepped one after another every frame (the order
 * rotates per frame), so machine load falls on every crop alike; the median and the minimum of
 * the per-step times are reported. */
static int crop_cost(const lod_opts *o)
{
    char model_path[1300];
    if (o->cost_model) {
        snprintf(model_path, sizeof model_path, "%s", o->cost_model);
    } else {
        snprintf(model_path, sizeof model_path, "%s/game.safetensors", o->models);
    }
    const size_t n = o->ncrops;
    const uint32_t frames = o->scale_frames, lead = 4;
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_body *body = NULL;
    weft_cloth_mesh *cloth = NULL;
    weft_model *model = NULL;
    weft_garment *g[LOD_MAX_CROPS] = {NULL};
    weft_avatar_def ad = weft_default_avatar_def();
    weft_cloth_def cl = weft_default_cloth_def(WEFT_CLOTH_TSHIRT);
    bool ok = weft_context_create(&cd, &ctx) == WEFT_OK && weft_avatar_create(ctx, &ad, &body) == WEFT_OK &&
              weft_cloth_resolution_from_name(o->scale_res, &cl.resolution) == WEFT_OK &&
              weft_cloth_create(ctx, &cl, body, &cloth) == WEFT_OK &&
              weft_model_load_file(ctx, model_path, &model) == WEFT_OK;
    const uint32_t nb = ok ? weft_body_vertex_count(body) : 0;
    float *verts = ok ? malloc((size_t)nb * 3 * sizeof(float)) : NULL;
    double *ms = calloc((size_t)n * frames, sizeof *ms);
    double tokens[LOD_MAX_CROPS] = {0};
    ok = ok && verts && ms;
    for (size_t k = 0; ok && k < n; ++k) {
        weft_garment_def d = weft_default_garment_def();
        d.method = WEFT_METHOD_MODEL;
        d.model = model;
        d.ccd.enabled = false;
        d.collider_crop_margin = (float)(o->crops[k].cm / 100.0);
        d.collider_crop = o->crops[k].cells ? WEFT_COLLIDER_CROP_CELLS : WEFT_COLLIDER_CROP_BOX;
        d.max_collider_tokens = o->crops[k].tokens;
        d.rest_positions = cloth->positions;
        d.vertex_count = cloth->vertex_count;
        d.triangles = cloth->triangles;
        d.triangle_count = cloth->triangle_count;
        d.collider_rest_positions = weft_body_rest_vertices(body);
        d.collider_vertex_count = nb;
        d.collider_triangles = weft_body_triangles(body);
        d.collider_triangle_count = weft_body_triangle_count(body);
        ok = weft_garment_create(ctx, &d, &g[k]) == WEFT_OK;
    }
    weft_motion_def md = weft_default_motion_def(WEFT_MOTION_WALK);
    for (uint32_t f = 0; ok && f < lead + frames; ++f) {
        weft_pose pose, bind;
        ok = weft_motion_sample(&md, (double)f / 60.0, &pose) == WEFT_OK;
        if (ok && f < lead) { /* blend in from the bind pose the garments were made on (untimed) */
            weft_body_bind_pose(body, &bind);
            const float u = (float)(f + 1) / (float)lead;
            for (int j = 0; j < 3 * WEFT_BODY_JOINTS; ++j) {
                pose.rotations[j] = bind.rotations[j] + u * (pose.rotations[j] - bind.rotations[j]);
            }
        }
        ok = ok && weft_body_pose(body, &pose, verts, NULL) == WEFT_OK;
        for (size_t i = 0; ok && i < n; ++i) {
            const size_t k = (i + f) % n;
            ok = weft_garment_set_collider(g[k], verts) == WEFT_OK && weft_garment_step(g[k]) == WEFT_OK;
            if (ok && f >= lead) {
                const weft_step_stats st = weft_garment_stats(g[k]);
                ms[k * frames + (f - lead)] = st.step_ms;
                tokens[k] += st.collider_tokens;
            }
        }
    }
    int rc = 0;
    if (!ok) {
        fprintf(stderr, "weft bench lod --crop-cost: %s\n", weft_last_error());
        rc = 1;
    } else {
        printf("crop cost: %s fp32, CCD off, default avatar (%u triangles) walking, T-shirt %s (%u vertices); "
               "%u timed frames after %u blend-in frames, garments stepped in turn\n",
               model_path, weft_body_triangle_count(body), o->scale_res, cloth->vertex_count, frames, lead);
        printf("%-24s %12s %12s %14s\n", "crop", "median ms", "min ms", "tokens/frame");
        for (size_t k = 0; k < n; ++k) {
            double *row = ms + k * frames;
            qsort(row, frames, sizeof *row, cmp_double);
            const double med = frames % 2 ? row[frames / 2] : 0.5 * (row[frames / 2 - 1] + row[frames / 2]);
            char name[64];
            if (o->crops[k].cm > 0.0) {
                snprintf(name, sizeof name, "%.4g cm %s", o->crops[k].cm, o->crops[k].cells ? "cells" : "box");
            } else {
                snprintf(name, sizeof name, "model's, %s", o->crops[k].cells ? "cells" : "box");
            }
            if (o->crops[k].tokens) {
                const size_t used = strlen(name);
                snprintf(name + used, sizeof name - used, " @%u", o->crops[k].tokens);
            }
            printf("%-24s %12.3f %12.3f %14.0f\n", name, med, row[0], tokens[k] / frames);
        }
    }
    for (size_t k = 0; k < n; ++k) {
        weft_garment_destroy(g[k]);
    }
    free(verts);
    free(ms);
    weft_model_destroy(model);
    weft_cloth_destroy(cloth);
    weft_body_destroy(body);
    if (ctx) {
        weft_context_destroy(ctx);
    }
    return rc;
}

/* ---------------------------------------------------------------------------------------- */
/* LOD.md: replace the generated blocks (bench_replace_block), keep the rest.                   */

static char *table_block(const lod_cand *c, size_t nc, const char *command, const lod_opts *o, double wall,
                         char skipped[][300], size_t nskip, const char *csv_name, const char *csv_link)
{
    size_t len = 0, cap = 0;
    char *s = NULL, line[4096];
    time_t now = time(NULL);
    char date[64];
    strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", gmtime(&now));
    snprintf(line, sizeof line,
             "Generated by `%s` on %s in %.0f s (data `%s`, split `%s`%s). Build and machine: `%s`. "
             "The table: [%s](%s).\n\n",
             command, date, wall, o->data, o->split, o->frames ? ", rollouts cut at --frames" : "",
             weft_config_string(), csv_name, csv_link);
    s = bench_append(s, &len, &cap, line);
    s = s ? bench_append(s, &len, &cap,
                   "| level | method | precision | substeps | CCD | collider crop | resolution | sequences | frames | "
                   "ms/frame | MVE (cm) | max edge strain | in lod.csv |\n"
                   "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n")
          : NULL;
    /* Cheapest first. */
    bool done[LOD_MAX_CANDS] = {false};
    for (size_t pass = 0; s && pass < nc; ++pass) {
        size_t best = nc;
        for (size_t k = 0; k < nc; ++k) {
            if (done[k]) {
                continue;
            }
            double mk = c[k].frames ? c[k].ms_w / c[k].frames : INFINITY;
            double mb = best < nc && c[best].frames ? c[best].ms_w / c[best].frames : INFINITY;
            if (best == nc || mk < mb) {
                best = k;
            }
        }
        done[best] = true;
        const lod_cand *k = &c[best];
        double w = k->frames ? (double)k->frames : NAN;
        char sub[16] = "-";
        if (k->substeps) {
            snprintf(sub, sizeof sub, "%u", k->substeps);
        }
        char crop[64] = "-";
        if (strcmp(k->family, "model") == 0) {
            if (k->crop.cm > 0.0) {
                snprintf(crop, sizeof crop, "%.4g cm %s", k->crop.cm, k->crop.cells ? "cells" : "box");
            } else {
                snprintf(crop, sizeof crop, "model's, %s", k->crop.cells ? "cells" : "box");
            }
            if (k->crop.tokens) {
                const size_t used = strlen(crop);
                snprintf(crop + used, sizeof crop - used, ", at most %u", k->crop.tokens);
            }
        }
        char res[64] = "1";
        if (k->sim) {
            snprintf(res, sizeof res, "%.2f (coarse mesh)", o->sim_res[k->sim - 1]);
        }
        snprintf(line, sizeof line, "| %s | %s%s%s | %s | %s | %s | %s | %s | %u | %u | %.3f | %.3f | %.3f | %s |\n",
                 k->name, k->family, k->model_name[0] ? " " : "", k->model_name, k->precision[0] ? k->precision : "-",
                 sub, k->ccd ? "on" : "off", crop, res, k->sequences, k->frames, k->ms_w / w, k->mve_w / w, k->strain,
                 cand_valid(k) ? "yes" : (k->nan_runs ? "no: NaN" : "no: failed"));
        s = bench_append(s, &len, &cap, line);
    }
    for (size_t i = 0; s && i < nskip; ++i) {
        snprintf(line, sizeof line, "%s- not measured: %.299s\n", i == 0 ? "\n" : "", skipped[i]);
        s = bench_append(s, &len, &cap, line);
    }
    for (size_t k = 0; s && k < nc; ++k) {
        if (!cand_valid(&c[k]) && c[k].note[0]) {
            snprintf(line, sizeof line, "- `%.47s` left out of lod.csv: %.239s\n", c[k].name, c[k].note);
            s = bench_append(s, &len, &cap, line);
        }
    }
    return s ? bench_append(s, &len, &cap, "\n") : NULL;
}

static char *scaling_block(const scale_row *r, size_t n, const char *desc, const lod_opts *o, const char *command)
{
    size_t len = 0, cap = 0;
    char *s = NULL, line[4096];
    snprintf(line, sizeof line,
             "Measured by `%s`: %s; median over %u timed frames after 4 untimed blend-in frames, one "
             "thread, CCD as in the level. *sequential*: `weft_lod_garment_step` per character; *batched*: one `weft_garments_step` "
             "call over all characters (model garments sharing a model and precision run the temporal "
             "transformer as one stacked GEMM per layer; other methods are stepped one by one inside it).\n\n",
             command, desc, o->scale_frames);
    s = bench_append(s, &len, &cap, line);
    s = s ? bench_append(s, &len, &cap,
                   "| level | stepping | ms/character at 1 | at 8 | at 64 | total ms/frame at 64 |\n"
                   "|---|---|---|---|---|---|\n")
          : NULL;
    for (size_t i = 0; s && i + 2 < n; i += 3) {
        snprintf(line, sizeof line, "| %.47s | %s | %.3f | %.3f | %.3f | %.1f |\n", r[i].level,
                 r[i].batched ? "batched" : "sequential", r[i].ms_per_char, r[i + 1].ms_per_char, r[i + 2].ms_per_char,
                 r[i + 2].ms_total);
        s = bench_append(s, &len, &cap, line);
    }
    return s ? bench_append(s, &len, &cap, "\n") : NULL;
}

/* Part 2 alone, on the table already in CSVDIR/lod.csv. */
static int scale_only(const lod_opts *o, const char *command)
{
    char csv[1200], md[1200];
    snprintf(csv, sizeof csv, "%s/lod.csv", o->csv_dir);
    snprintf(md, sizeof md, "%s/LOD.md", o->out);
    static scale_row rows[LOD_MAX_SCALE * 6];
    char desc[256] = "";
    size_t nr = run_scaling(o, csv, rows, sizeof rows / sizeof rows[0], desc, sizeof desc);
    if (nr == 0) {
        fprintf(stderr, "weft bench lod: nothing measured (is %s there? run without --scale-only first)\n", csv);
        return 1;
    }
    char *block = scaling_block(rows, nr, desc, o, command);
    char *doc = block ? bench_replace_block(bench_slurp(md, NULL), "lod:scaling", block, "# Level of detail\n") : NULL;
    free(block);
    return bench_write_doc("lod", md, doc) ? 0 : 1;
}

int weft_bench_lod(int argc, char **argv)
{
    lod_opts o = {.split = "test", .models = "tools/train/models", .out = "docs", .scale = true, .scale_frames = 4,
                  .scale_res = "1k", .name = "lod"};
    char command[2048];
    bench_command_line(command, sizeof command, "weft bench lod", argc, argv);
    cli_parser cp;
    cli_start(&cp, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&cp, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        switch (id) {
        case CLI_STOP:
            return cp.exit;
        case OPT_NO_SCALE:
            o.scale = false;
            break;
        case OPT_SCALE_ONLY:
            o.scale_only = true;
            break;
        case OPT_CROP_COST:
            o.crop_cost = true;
            break;
        case OPT_DATA:
            o.data = v;
            break;
        case OPT_SPLIT:
            o.split = v;
            break;
        case OPT_MODELS:
            o.models = v;
            break;
        case OPT_OUT:
            o.out = v;
            break;
        case OPT_CSV_DIR:
            o.csv_dir = v;
            break;
        case OPT_CROP_MODEL:
            o.cost_model = v;
            break;
        case OPT_SCENARIO:
            o.scenario = v;
            break;
        case OPT_NAME:
            o.name = v;
            for (const char *p = v; *p; ++p) {
                if (!((*p >= 'a' && *p <= 'z') || (*p >= '0' && *p <= '9') || *p == '_' || *p == '-') || p - v > 40) {
                    fprintf(stderr, "weft bench lod: --name wants [a-z0-9_-], at most 40 characters\n");
                    return 2;
                }
            }
            break;
        case OPT_PUSH_CM:
            if (!cli_double(k_command.tool, a, v, 0.01, 10.0, &o.push_cm)) {
                return 2;
            }
            break;
        case OPT_TETHER_CM:
        case OPT_STRAIN_LIMIT:
            if (!cli_double(k_command.tool, a, v, 0.01, 1000.0, id == OPT_TETHER_CM ? &o.tether_cm : &o.strain_pct)) {
                return 2;
            }
            break;
        case OPT_SIM_DATA:
            if (o.nsim == LOD_MAX_SIM) {
                fprintf(stderr, "weft bench lod: at most %d --sim-data folders\n", LOD_MAX_SIM);
                return 2;
            }
            o.sim_data[o.nsim++] = v;
            break;
        case OPT_SCALE_LEVELS:
            o.scale_levels = v;
            break;
        case OPT_SCALE_RES:
            o.scale_res = v;
            break;
        case OPT_CROPS:
            if ((o.ncrops = parse_crops(v, o.crops, LOD_MAX_CROPS)) == 0) {
                fprintf(stderr, "weft bench lod: --crops wants up to %d items like model,8,4:cells,model@3000\n",
                        LOD_MAX_CROPS);
                return 2;
            }
            break;
        case OPT_XPBD:
            if (!bench_parse_substeps("lod", a, v, o.xpbd, 8, &o.nxpbd)) {
                return 2;
            }
            break;
        case OPT_FRAMES:
        case OPT_MAX_SEQS:
        case OPT_SCALE_FRAMES:
            if (!bench_parse_u32("lod", a, v, id == OPT_SCALE_FRAMES ? 1 : 0, 1000000,
                                 id == OPT_FRAMES ? &o.frames : id == OPT_MAX_SEQS ? &o.max_seqs : &o.scale_frames)) {
                return 2;
            }
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&cp) != 0) {
        return 2;
    }
    weft_cloth_resolution res_check;
    if (weft_cloth_resolution_from_name(o.scale_res, &res_check) != WEFT_OK) {
        fprintf(stderr, "weft bench lod: --scale-res must be 1k, 4k, 16k or 40k\n");
        return 2;
    }
    o.csv_dir = bench_csv_dir(o.csv_dir, o.out, LOD_TABLE_DIR);
    if (o.ncrops == 0) {
        o.crops[0] = (lod_crop){0.0, false, 0};
        o.ncrops = 1;
    }
    if (o.crop_cost) {
        return crop_cost(&o);
    }
    if (o.scale_only) {
        return scale_only(&o, command);
    }
    if (!o.data) {
        return cli_fail(&k_command, "--data is required");
    }
    if (o.nxpbd == 0) {
        static const unsigned k_sub[] = {5, 10, 20};
        memcpy(o.xpbd, k_sub, sizeof k_sub);
        o.nxpbd = 3;
    }
    char exe[1024];
    bench_seq *seqs = NULL;
    size_t nseq = 0;
    if (!bench_start("lod", o.data, o.split, o.out, exe, sizeof exe, &seqs, &nseq)) {
        return 1;
    }
    if (o.scenario) {
        size_t kept = 0;
        for (size_t i = 0; i < nseq; ++i) {
            if (strcmp(seqs[i].scenario, o.scenario) == 0) {
                seqs[kept++] = seqs[i];
            }
        }
        nseq = kept;
        if (nseq == 0) {
            fprintf(stderr, "weft bench lod: no %s sequences of scenario '%s' under %s\n", o.split, o.scenario, o.data);
            free(seqs);
            return 1;
        }
    }
    if (o.max_seqs) { /* per scenario, as `weft bench chart` counts them (the split lists them by name) */
        size_t kept = 0;
        for (size_t i = 0; i < nseq; ++i) {
            uint32_t same = 0;
            for (size_t j = 0; j < kept; ++j) {
                same += strcmp(seqs[j].scenario, seqs[i].scenario) == 0;
            }
            if (same < o.max_seqs) {
                seqs[kept++] = seqs[i];
            }
        }
        nseq = kept;
    }
    if (o.nsim && !pair_sim_meshes(&o, seqs, nseq)) {
        free(o.sim_dir);
        free(seqs);
        return 1;
    }
    weft_context_def cdef = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cdef, &ctx) != WEFT_OK) {
        fprintf(stderr, "weft bench lod: %s\n", weft_last_error());
        free(o.sim_dir);
        free(seqs);
        return 1;
    }
    static lod_cand cands[LOD_MAX_CANDS];
    static char skipped[16][300];
    size_t nskip = 0;
    size_t nc = build_candidates(ctx, &o, cands, skipped, &nskip);
    weft_context_destroy(ctx);

    double t0 = now_s();
    run_candidates(exe, &o, seqs, nseq, cands, nc);
    double wall = now_s() - t0;
    free(o.sim_dir);
    o.sim_dir = NULL;
    free(seqs);

    char csv[1200], md[1200], csv_name[64], csv_link[1200];
    snprintf(csv, sizeof csv, "%s/%s.csv", o.csv_dir, o.name);
    snprintf(csv_name, sizeof csv_name, "%s.csv", o.name);
    const bool main_table = strcmp(o.name, "lod") == 0;
    char table_tag[64], scaling_tag[64];
    snprintf(table_tag, sizeof table_tag, main_table ? "lod:table" : "lod:table-%s", o.name);
    snprintf(scaling_tag, sizeof scaling_tag, main_table ? "lod:scaling" : "lod:scaling-%s", o.name);
    snprintf(md, sizeof md, "%s/LOD.md", o.out);
    size_t valid = 0;
    for (size_t k = 0; k < nc; ++k) {
        valid += cand_valid(&cands[k]);
    }
    if (valid == 0) {
        fprintf(stderr, "weft bench lod: no level produced a valid measurement; %s not written\n", csv);
        return 1;
    }
    if (!bench_mkdirs(o.csv_dir)) {
        fprintf(stderr, "weft bench lod: cannot create %s\n", o.csv_dir);
        return 1;
    }
    if (!write_csv(csv, cands, nc, command, &o)) {
        return 1;
    }
    printf("wrote %s (%zu levels)\n", csv, valid);

    bench_link(o.out, o.csv_dir, csv_name, csv_link, sizeof csv_link);
    char *doc = bench_slurp(md, NULL);
    char *block = table_block(cands, nc, command, &o, wall, skipped, nskip, csv_name, csv_link);
    doc = block ? bench_replace_block(doc, table_tag, block, "# Level of detail\n") : NULL;
    free(block);
    if (o.scale && doc) {
        static scale_row rows[LOD_MAX_SCALE * 6];
        char desc[256] = "";
        size_t nr = run_scaling(&o, csv, rows, sizeof rows / sizeof rows[0], desc, sizeof desc);
        block = nr ? scaling_block(rows, nr, desc, &o, command) : NULL;
        doc = block ? bench_replace_block(doc, scaling_tag, block, "# Level of detail\n") : doc;
        free(block);
    }
    return bench_write_doc("lod", md, doc) ? 0 : 1;
}
