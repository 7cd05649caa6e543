/* weft bench chart: speed against accuracy for every method on a held-out split.
 *
 * Every (method, sequence) pair is one `weft eval --json` child process (same code path as the
 * user-facing command). Results are aggregated per scenario and method with frame-weighted means,
 * the Pareto front (lower ms and lower error) is marked, and the run writes <out>/CHART.md, the
 * CSV behind it (<csv-dir>/chart.csv: docs/data when <out> is docs, else <out>) and, through
 * tools/bench/plot_chart.py, <out>/img/chart.png. The FNOpt grid scenes are scored by `weft
 * fnopt run --gt` (relative e3D against its XPBD reference, a different metric from MVE, so they
 * get their own panel). */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include "weft.h"
#include "support_bench.h"
#include "support_cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

const char weft_bench_chart_help[] = "speed vs accuracy of every method on a test split: CSV, markdown table, PNG chart";

/* The 1-minute load average (Linux /proc/loadavg), so the page says how busy the machine was
 * while the wall-clock timings were taken; "unknown" elsewhere. */
static void read_loadavg(char *buf, size_t size)
{
    snprintf(buf, size, "unknown");
    FILE *f = fopen("/proc/loadavg", "r");
    if (f) {
        double l1 = 0.0;
        if (fscanf(f, "%lf", &l1) == 1) {
            snprintf(buf, size, "%.2f", l1);
        }
        fclose(f);
    }
}

static char chart_load_start[32];

#define CHART_MAX_METHODS 128
#define CHART_MAX_SCEN 16

typedef struct chart_method {
    char label[96];
    char family[16];    /* lbs, xpbd, xpbd-fast, model, fnopt */
    char method[16];    /* --method value, or the FNOpt optimizer */
    char precision[8];  /* fp32 fp16 int8, "-" for methods without one */
    char model[1024];
    bool ccd;
    char tether_cm[8];  /* "" or `weft eval --tether-cm` */
    char strain_pct[8]; /* "" or `weft eval --strain-limit` */
    char strain_contact_cm[8]; /* "" or `weft eval --strain-contact-cm` */
    char push_cm[8];    /* "" or `weft eval --push-cm` */
    bool garment_only;  /* tethers bind to the wearer: run on garment sequences only */
    bool mocap;         /* a row of the real-motion panel (`weft bench mocap`) */
} chart_method;

typedef struct chart_row {
    char scenario[32];
    int method;
    uint32_t sequences, frames, nan_runs, exploded_runs;
    double mve_w, e3d_w, coll_w, self_w, ms_w, max_strain;
    double inside_w;       /* real motion: sum of the cells' mean inside_body % (cells in `sequences`) */
    uint32_t lost;         /* real motion: cells whose garment was lost */
    bool pareto;
    char note[240];
} chart_row;

typedef struct chart_opts {
    const char *data, *split, *models, *out, *fnopt_model;
    const char *csv_dir; /* where chart.csv goes (bench_csv_dir) */
    uint32_t frames, max_seqs;
    unsigned xpbd[8];
    size_t nxpbd;
    unsigned xpbd_fast[8]; /* WEFT_METHOD_XPBD_FAST substep counts */
    size_t nxpbd_fast;
    const char *fnopt_motions;
    uint32_t mocap_frames; /* frames per cell of the real-motion panel */
    const char *mocap_clips, *mocap_garments;
    bool quick, plot, fnopt, frames_given, mocap;
} chart_opts;

/* The real-motion panel's methods: each shipped method at its defaults (`weft bench mocap`). */
#define CHART_MOCAP_METHODS "lbs,model,xpbd-fast:5,xpbd-fast:10,fnopt"
#define CHART_MOCAP_METHODS_CLASSIC "lbs,xpbd-fast:5,xpbd-fast:10,fnopt" /* without a shipped model */
#define CHART_MOCAP_SCENARIO "mocap"
/* The render sample's cape on the same clips: FNOpt and the fast XPBD on one 32 x 40 grid. */
#define CHART_CAPE_SCENARIO "cape"
#define CHART_MOCAP_GARMENTS "tshirt,dress,skirt,cape"
#define CHART_MOCAP_GARMENTS_ONLY "tshirt,dress,skirt" /* without the FNOpt weights */
#define CHART_MOCAP_METHODS_GARMENTS "lbs,model,xpbd-fast:5,xpbd-fast:10"
#define CHART_MOCAP_METHODS_GARMENTS_CLASSIC "lbs,xpbd-fast:5,xpbd-fast:10"

enum {
    OPT_DATA = 1, OPT_SPLIT, OPT_MODELS, OPT_FRAMES, OPT_OUT, OPT_CSV_DIR, OPT_MAX_SEQS, OPT_XPBD, OPT_XPBD_FAST,
    OPT_QUICK, OPT_NO_PLOT, OPT_NO_FNOPT, OPT_FNOPT_MODEL, OPT_FNOPT_MOTIONS, OPT_NO_MOCAP, OPT_MOCAP_FRAMES,
    OPT_MOCAP_CLIPS, OPT_MOCAP_GARMENTS,
};

static const cli_option k_options[] = {
    {"data", "DIR", OPT_DATA, "the simgen sequences (required)"},
    {"split", "test|val|train|all", OPT_SPLIT, "the split scored (default test)"},
    {"models", "DIR", OPT_MODELS, "every DIR/*.safetensors model is charted (default tools/train/models)"},
    {"frames", "N", OPT_FRAMES, "cut every rollout at N predicted frames, 0..1000000 (default 0: whole sequences)"},
    {"max-seqs", "N", OPT_MAX_SEQS, "at most N sequences per scenario, 0..1000000 (default 0: all)"},
    {"xpbd", "5,10,20,40", OPT_XPBD, "substep counts of the reference XPBD rows"},
    {"xpbd-fast", "5,10,20,40", OPT_XPBD_FAST,
     "substep counts of the fast XPBD rows (a game's collision projection; CCD off,\n"
     "and CCD on at the first count)"},
    {"out", "DIR", OPT_OUT, "where CHART.md and img/chart.png go (default docs)"},
    {"csv-dir", "DIR", OPT_CSV_DIR, "where chart.csv goes (default docs/data when --out is docs, else --out)"},
    {"quick", NULL, OPT_QUICK, "30 frames, at most 2 sequences per scenario, one FNOpt scene (xy)"},
    {"no-plot", NULL, OPT_NO_PLOT, "write the tables, not the figure"},
    {"no-fnopt", NULL, OPT_NO_FNOPT, "leave out the FNOpt grid scenes"},
    {"fnopt-model", "PATH", OPT_FNOPT_MODEL, "the FNOpt weights (default tools/fnopt/models/fnopt_32.safetensors)"},
    {"fnopt-motions", "xy,xyz,rot_h0", OPT_FNOPT_MOTIONS, "the FNOpt grid scenes run (default all three; --quick: xy)"},
    {"no-mocap", NULL, OPT_NO_MOCAP, "leave out the real-motion panel"},
    {"mocap-frames", "N", OPT_MOCAP_FRAMES,
     "frames per clip and garment of the real-motion panel, 1..100000 (default 150;\n"
     "--quick: 30)"},
    {"mocap-clips", "A,B,...", OPT_MOCAP_CLIPS, "its clips (default: the mocap library's test split; --quick: walk_cmu07_01)"},
    {"mocap-garments", "LIST", OPT_MOCAP_GARMENTS,
     "its garments (default " CHART_MOCAP_GARMENTS "; --quick: tshirt,cape); the cape is its\n"
     "own panel (FNOpt and the fast XPBD on the render sample's cape)"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft bench chart",
    .synopsis = "weft bench chart --data DIR [options]",
    .about = "Runs LBS, the reference XPBD, the fast XPBD, every learned model (fp32/fp16/int8, CCD on and\n"
             "off) on each sequence of the split, and the FNOpt grid scenes, each as one `weft eval --json`\n"
             "(or `weft fnopt run --gt`) run; writes OUT/CHART.md, OUT/img/chart.png and the CSV behind them.\n"
             "The real-motion panel runs `weft bench mocap` (" CHART_MOCAP_METHODS ", each at its\n"
             "defaults, on the library's test clips): the reference's ground truth covers few real-motion\n"
             "windows (docs/DATASET.md), so its error axis is the share of cloth inside the body, and lost\n"
             "garments are counted. The render sample's\n"
             "cape on the same clips is a panel of its own: FNOpt (K = 10) beside the fast XPBD on one grid.\n"
             "A run that fails (a child that cannot start, crashes or reports an error) fails the whole\n"
             "benchmark: nothing is written from partial results.",
    .options = k_options,
};

/* A row of the real-motion panels (the garments' or the cape's): scored by inside_body. */
static bool is_mocap(const chart_row *r)
{
    return strcmp(r->scenario, CHART_MOCAP_SCENARIO) == 0 || strcmp(r->scenario, CHART_CAPE_SCENARIO) == 0;
}
static bool is_cape(const chart_row *r) { return strcmp(r->scenario, CHART_CAPE_SCENARIO) == 0; }

/* The panel's error: inside_body % on real motion, e3D for FNOpt's grid scenes, MVE elsewhere. */
static double row_error(const chart_row *r, const chart_method *m)
{
    uint32_t w = r->frames;
    if (w == 0) {
        return NAN;
    }
    return is_mocap(r) ? r->inside_w / w : strcmp(m->family, "fnopt") == 0 ? r->e3d_w / w : r->mve_w / w;
}

static bool row_valid(const chart_row *r, const chart_method *m)
{
    return r->frames > 0 && r->nan_runs == 0 && isfinite(row_error(r, m));
}

static chart_row *find_row(chart_row *rows, size_t *n, size_t cap, const char *scenario, int method)
{
    for (size_t i = 0; i < *n; ++i) {
        if (rows[i].method == method && strcmp(rows[i].scenario, scenario) == 0) {
            return &rows[i];
        }
    }
    if (*n == cap) {
        return NULL;
    }
    chart_row *r = &rows[(*n)++];
    memset(r, 0, sizeof *r);
    snprintf(r->scenario, sizeof r->scenario, "%s", scenario);
    r->method = method;
    return r;
}

static void add_note(chart_row *r, const char *why)
{
    if (!r->note[0] && why && why[0]) {
        snprintf(r->note, sizeof r->note, "%s", why);
    }
}

/* One FNOpt grid scene: `weft fnopt run --gt` prints a CSV header and one row. */
static bool run_fnopt(const char *exe, const chart_opts *o, const chart_method *m, const char *motion, chart_row *r)
{
    char frames[16];
    /* The whole trajectory unless --frames was given: the handles start moving only after a rest
     * phase, so a short cut scores nothing but the cloth settling. */
    snprintf(frames, sizeof frames, "%u", o->frames_given ? o->frames : 0u);
    const char *argv[20];
    int n = 0;
    argv[n++] = exe;
    argv[n++] = "fnopt";
    argv[n++] = "run";
    argv[n++] = "--gt";
    argv[n++] = "--material";
    argv[n++] = BENCH_FNOPT_MATERIAL;
    argv[n++] = "--motion";
    argv[n++] = motion;
    argv[n++] = "--optimizer";
    argv[n++] = m->method;
    argv[n++] = "--frames";
    argv[n++] = frames;
    if (strcmp(m->method, "learned") == 0) {
        argv[n++] = "--model";
        argv[n++] = m->model;
    }
    argv[n] = NULL;
    char *out = NULL, why[240];
    int rc = bench_spawn(argv, &out, why, sizeof why);
    /* The columns by their header names, so that a column added to `weft fnopt run` does not shift
     * what is read: frames, diverged, ms_per_frame and e3d. */
    unsigned fr = 0;
    int diverged = 0;
    double ms = NAN, e3d = NAN;
    int found = 0;
    const char *row = out ? strchr(out, '\n') : NULL;
    if (rc == 0 && row) {
        const char *h = out, *v = row + 1;
        while (h < row && *v && *v != '\n') {
            const size_t hn = strcspn(h, ",\n"), vn = strcspn(v, ",\n");
            char val[64];
            snprintf(val, sizeof val, "%.*s", (int)(vn < sizeof val ? vn : sizeof val - 1), v);
            char *end = NULL;
            if (hn == 6 && strncmp(h, "frames", 6) == 0) {
                const unsigned long x = strtoul(val, &end, 10);
                fr = (unsigned)x;
                found += end != val && *end == '\0';
            } else if (hn == 8 && strncmp(h, "diverged", 8) == 0) {
                diverged = (int)strtol(val, &end, 10);
                found += end != val && *end == '\0';
            } else if (hn == 12 && strncmp(h, "ms_per_frame", 12) == 0) {
                ms = strtod(val, &end);
                found += end != val && *end == '\0';
            } else if (hn == 3 && strncmp(h, "e3d", 3) == 0) {
                e3d = strtod(val, &end);
                found += end != val && *end == '\0';
            }
            h += hn + (h[hn] == ',');
            v += vn + (v[vn] == ',');
        }
    }
    const bool ok = found == 4;
    free(out);
    r->sequences++;
    if (!ok) {
        bench_sanitize(why);
        add_note(r, why[0] ? why : "fnopt printed no row with frames, diverged, ms_per_frame and e3d");
        return false;
    }
    if (diverged || !isfinite(e3d)) {
        r->nan_runs++;
        add_note(r, "diverged");
    }
    r->frames += fr;
    r->e3d_w += isfinite(e3d) ? e3d * fr : 0.0;
    r->ms_w += ms * fr;
    return true;
}

/* The method of a `weft bench mocap` cell ("lbs", "model int8", "xpbd-fast:5") as a chart method;
 * added to the list the first time it is seen. -1 when the list is full. */
static int mocap_method(chart_method *methods, size_t *nm, const char *name)
{
    char label[96], family[16], precision[8];
    unsigned S = 0;
    if (strcmp(name, "lbs") == 0) {
        snprintf(label, sizeof label, "LBS");
        snprintf(family, sizeof family, "lbs");
        snprintf(precision, sizeof precision, "-");
    } else if (strncmp(name, "model ", 6) == 0) {
        snprintf(label, sizeof label, "garment %.8s", name + 6);
        snprintf(family, sizeof family, "model");
        snprintf(precision, sizeof precision, "%.7s", name + 6);
    } else if (strncmp(name, "FNOpt ", 6) == 0) { /* the cape's FNOpt, "FNOpt fp32" */
        snprintf(label, sizeof label, "%.90s", name);
        snprintf(family, sizeof family, "fnopt");
        snprintf(precision, sizeof precision, "%.7s", name + 6);
    } else if (sscanf(name, "xpbd-fast:%u", &S) == 1) {
        snprintf(label, sizeof label, "XPBD-fast-%u", S);
        snprintf(family, sizeof family, "xpbd-fast");
        snprintf(precision, sizeof precision, "-");
    } else if (sscanf(name, "xpbd:%u", &S) == 1) {
        snprintf(label, sizeof label, "XPBD-%u", S);
        snprintf(family, sizeof family, "xpbd");
        snprintf(precision, sizeof precision, "-");
    } else {
        snprintf(label, sizeof label, "%.90s", name);
        snprintf(family, sizeof family, "other");
        snprintf(precision, sizeof precision, "-");
    }
    for (size_t k = 0; k < *nm; ++k) {
        if (methods[k].mocap && strcmp(methods[k].label, label) == 0) {
            return (int)k;
        }
    }
    if (*nm == CHART_MAX_METHODS) {
        return -1;
    }
    chart_method *m = &methods[(*nm)++];
    memset(m, 0, sizeof *m);
    snprintf(m->label, sizeof m->label, "%s", label);
    snprintf(m->family, sizeof m->family, "%s", family);
    snprintf(m->method, sizeof m->method, "%.15s", name);
    snprintf(m->precision, sizeof m->precision, "%s", precision);
    m->mocap = true;
    return (int)(*nm - 1);
}

/* The real-motion panel: one `weft bench mocap` child over the clips, garments and methods, its
 * per-cell CSV read back into one row per method (means over the cells, weighted by frames). The
 * child's CSV is kept as csv_cells (the per-cell table behind the panel). False (reported) when
 * the child fails or a cell is missing. */
/* The garments the real-motion run puts on: --mocap-garments, else the defaults (the cape only
 * with its FNOpt weights). */
static const char *mocap_garments(const chart_opts *o, bool cape)
{
    return o->mocap_garments ? o->mocap_garments
           : o->quick        ? (cape ? "tshirt,cape" : "tshirt")
           : cape            ? CHART_MOCAP_GARMENTS
                             : CHART_MOCAP_GARMENTS_ONLY;
}

static const char k_mocap_header[] = "clip,garment,method,lost,worst_off_body_pct,inside_body_mean_pct,";

static bool run_mocap(const char *exe, const chart_opts *o, const char *csv_cells, chart_method *methods, size_t *nm,
                      chart_row *rows, size_t *nrows, size_t row_cap, char *skipped, size_t skipped_cap)
{
    char frames[16], model[1100];
    snprintf(frames, sizeof frames, "%u", o->mocap_frames);
    /* The learned row is the shipped worn-garment model of --models, in int8 (its default). */
    snprintf(model, sizeof model, "%s/garment.int8.safetensors", o->models);
    const bool learned = bench_file_exists(model);
    /* The cape panel needs the FNOpt weights; without them the garments' panel runs alone. */
    const bool cape = bench_file_exists(o->fnopt_model);
    const char *method_list = learned ? CHART_MOCAP_METHODS : CHART_MOCAP_METHODS_CLASSIC;
    if (!cape) {
        method_list = learned ? CHART_MOCAP_METHODS_GARMENTS : CHART_MOCAP_METHODS_GARMENTS_CLASSIC;
    }
    const char *garments = mocap_garments(o, cape);
    if (!learned) {
        snprintf(skipped, skipped_cap, "real motion, learned model: no `%.200s`", model);
    } else if (!cape) {
        snprintf(skipped, skipped_cap, "the cape on real motion: no FNOpt weights `%.200s`", o->fnopt_model);
    }
    const char *argv[20];
    int n = 0;
    argv[n++] = exe;
    argv[n++] = "bench";
    argv[n++] = "mocap";
    argv[n++] = "--frames";
    argv[n++] = frames;
    argv[n++] = "--methods";
    argv[n++] = method_list;
    if (learned) {
        argv[n++] = "--model";
        argv[n++] = model;
    }
    argv[n++] = "--garments";
    argv[n++] = garments;
    if (cape) {
        argv[n++] = "--fnopt-model";
        argv[n++] = o->fnopt_model;
    }
    if (o->mocap_clips) {
        argv[n++] = "--clips";
        argv[n++] = o->mocap_clips;
    }
    argv[n++] = "--csv";
    argv[n++] = csv_cells;
    argv[n] = NULL;
    printf("real motion: weft bench mocap --frames %s --methods %s --garments %s%s%s --csv %s\n", frames,
           method_list, garments, o->mocap_clips ? " --clips " : "",
           o->mocap_clips ? o->mocap_clips : "", csv_cells);
    fflush(stdout);
    char *out = NULL, why[240];
    const int rc = bench_spawn(argv, &out, why, sizeof why);
    free(out);
    if (rc != 0) {
        bench_sanitize(why);
        fprintf(stderr, "weft bench chart: the real-motion run failed: %s; nothing written\n", why);
        return false;
    }
    FILE *f = fopen(csv_cells, "r");
    char line[1024];
    if (!f || !fgets(line, sizeof line, f) ||
        strncmp(line, k_mocap_header, sizeof k_mocap_header - 1) != 0) {
        fprintf(stderr, "weft bench chart: %s is not `weft bench mocap --csv` output; nothing written\n", csv_cells);
        if (f) {
            fclose(f);
        }
        return false;
    }
    size_t cells = 0;
    while (fgets(line, sizeof line, f)) {
        char clip[128], garment[32], method[64];
        int lost = 0;
        double off = NAN, inside = NAN, inside_max = NAN, self_mean = NAN, self_max = NAN, p50 = NAN;
        if (sscanf(line, "%127[^,],%31[^,],%63[^,],%d,%lf,%lf,%lf,%lf,%lf,%lf", clip, garment, method, &lost, &off,
                   &inside, &inside_max, &self_mean, &self_max, &p50) != 10 ||
            !isfinite(inside) || !isfinite(p50)) {
            fprintf(stderr, "weft bench chart: %s: unreadable cell '%.200s'; nothing written\n", csv_cells, line);
            fclose(f);
            return false;
        }
        const int k = mocap_method(methods, nm, method);
        const char *scenario = strcmp(garment, "cape") == 0 ? CHART_CAPE_SCENARIO : CHART_MOCAP_SCENARIO;
        chart_row *r = k >= 0 ? find_row(rows, nrows, row_cap, scenario, k) : NULL;
        if (!r) {
            fprintf(stderr, "weft bench chart: too many methods or rows; nothing written\n");
            fclose(f);
            return false;
        }
        const double w = o->mocap_frames;
        r->sequences++;
        r->frames += o->mocap_frames;
        r->inside_w += inside * w;
        r->ms_w += p50 * w;
        r->lost += lost != 0;
        ++cells;
    }
    fclose(f);
    if (cells == 0) {
        fprintf(stderr, "weft bench chart: the real-motion run scored no cell; nothing written\n");
        return false;
    }
    return true;
}

static bool write_outputs(const chart_opts *o, const chart_method *methods, const chart_row *rows, size_t nrows,
                          char skipped[][300], size_t nskipped, const char *command, double wall_s, const char *exe)
{
    char path[1200], csv[1200], link[1200];
    snprintf(csv, sizeof csv, "%s/chart.csv", o->csv_dir);
    FILE *f = bench_mkdirs(o->csv_dir) ? fopen(csv, "w") : NULL;
    if (!f) {
        fprintf(stderr, "weft bench chart: cannot write %s\n", csv);
        return false;
    }
    fprintf(f, "scenario,method,family,precision,ccd,sequences,frames,mve_cm,e3d,ms_per_frame,collision_rate,"
               "self_collision_rate,max_edge_strain,nan_runs,exploded_runs,pareto,note,inside_body_pct,garments_lost\n");
    for (size_t i = 0; i < nrows; ++i) {
        const chart_row *r = &rows[i];
        const chart_method *m = &methods[r->method];
        double w = r->frames ? (double)r->frames : NAN;
        bool fn = strcmp(m->family, "fnopt") == 0;
        fprintf(f, "%s,%s,%s,%s,%s,%u,%u,", r->scenario, m->label, m->family, m->precision, m->ccd ? "on" : "off",
                r->sequences, r->frames);
        if (is_mocap(r)) {
            fprintf(f, ",,%.6g,,,,", r->ms_w / w);
        } else if (fn) {
            fprintf(f, ",%.6g,%.6g,,,,", r->e3d_w / w, r->ms_w / w);
        } else {
            fprintf(f, "%.6g,,%.6g,%.6g,%.6g,%.6g,", r->mve_w / w, r->ms_w / w, r->coll_w / w, r->self_w / w,
                    r->max_strain);
        }
        fprintf(f, "%u,%u,%d,%s,", r->nan_runs, r->exploded_runs, r->pareto ? 1 : 0, r->note);
        if (is_mocap(r)) {
            fprintf(f, "%.6g,%u\n", r->inside_w / w, r->lost);
        } else {
            fprintf(f, ",\n");
        }
    }
    fclose(f);

    snprintf(path, sizeof path, "%s/CHART.md", o->out);
    f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "weft bench chart: cannot write %s\n", path);
        return false;
    }
    time_t now = time(NULL);
    char date[64];
    strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", gmtime(&now));
    char mocap_link[1200];
    bench_link(o->out, o->csv_dir, "chart_mocap.csv", mocap_link, sizeof mocap_link);
    fprintf(f, "# Speed against accuracy\n\n");
    fprintf(f, "![ms/frame against error, one panel per scenario](img/chart.png)\n\n");
    fprintf(f, "Generated by `weft bench chart` on %s in %.0f s:\n\n```\n%s\n```\n\n", date, wall_s, command);
    char load_end[32];
    read_loadavg(load_end, sizeof load_end);
    fprintf(f, "Machine and build: `%s`; %ld online CPU(s), 1-minute load average %s at the start and %s at the "
               "end of the run (a load above the CPU count means the timings include waiting for a core).\n\n",
            weft_config_string(), sysconf(_SC_NPROCESSORS_ONLN), chart_load_start, load_end);
    fprintf(f, "Data: `%s`, split `%s`. Each (method, sequence) is one `weft eval --json` run: the rollout "
               "starts from the first two ground-truth frames and then sees only the collider. MVE is the mean "
               "vertex error in cm; means are weighted by scored frames. ms/frame is the wall time of "
               "`weft_garment_step` (CCD post-processing included when on), on a machine shared with other jobs, "
               "so treat small differences as noise. Pareto-front methods (nothing else is both faster and more "
               "accurate) are marked **bold**. NaN: rollouts that produced a non-finite state (stopped there); "
               "exploded: more than 1%% of the edges strained over 25%% in some frame (the stability suite's "
               "rule; the max edge strain column is the single worst edge).\n\n",
            o->data, o->split);
    if (o->frames) {
        fprintf(f, "Every rollout was cut at %u predicted frames.\n\n", o->frames);
    }
    fprintf(f, "Reading the numbers: the ground truth comes from `weft simgen`, itself an XPBD solver (double "
               "precision, 40 substeps, retried with more when its validator rejects a sequence). The runtime's "
               "XPBD at the same substep count is therefore close to the reference by construction where the "
               "two share their material model; it is the accuracy ceiling of the classical path, not an "
               "independent check. LBS carries the cloth rigidly with the collider: its error is what a "
               "method that simulates nothing scores. Learned models in fp16/int8 load `MODEL.fp16/int8.safetensors` "
               "(`weft quantize` output) when present, else the runtime converts the fp32 file.\n\n");
    for (size_t pass = 0; pass < nrows; ++pass) {
        /* One table per scenario, in first-seen order. */
        const char *sc = rows[pass].scenario;
        bool seen = false;
        for (size_t k = 0; k < pass; ++k) {
            seen = seen || strcmp(rows[k].scenario, sc) == 0;
        }
        if (seen) {
            continue;
        }
        bool fn = strcmp(methods[rows[pass].method].family, "fnopt") == 0;
        const bool mo = is_mocap(&rows[pass]);
        fprintf(f, "## %s\n\n", is_cape(&rows[pass]) ? "cape (real motion)" : mo ? "mocap (real motion)" : sc);
        if (is_cape(&rows[pass])) {
            fprintf(f, "The render sample's cape (a 32 x 40 grid pinned along its top row behind the shoulders; "
                       "docs/FNOPT.md, *The cape on the avatar*) on the same clips, %u frames each after the "
                       "30-frame settle: FNOpt (K = 10 iterations a frame, the shipped weights) and the fast XPBD "
                       "step the same grid with the same pins, body collision and attachments (`weft bench mocap "
                       "--garments cape`, cells in [chart_mocap.csv](%s)). The error is the share of cape vertices "
                       "inside the body; a cape is lost when more than 1 %% of its vertices are torn from their "
                       "pins (farther than 1.25 times their rest distance plus 5 cm). ms/frame is the mean of the "
                       "cells' median step.\n\n",
                    o->mocap_frames, mocap_link);
            fprintf(f, "| method | cells | capes lost | inside_body %% | ms/frame |\n|---|---|---|---|---|\n");
        } else if (mo) {
            fprintf(f, "The mocap library's clips (%s), garments %s, %u frames each after a 30-frame settle, "
                       "every method at its defaults (the worn-garment recipe, CCD off): `weft bench mocap`, "
                       "per-cell numbers in [chart_mocap.csv](%s). The reference's ground truth covers few "
                       "real-motion windows (docs/DATASET.md), so the error is the share of cloth vertices inside the body (mean over frames and cells), "
                       "beside the garments lost (a frame with over 1 %% of the vertices farther than 10 cm, "
                       "25 cm for skirts and dresses, from the skinned garment; docs/STABILITY_MOCAP.md). ms/frame "
                       "is the mean of the cells' median step.\n\n",
                    o->mocap_clips ? o->mocap_clips : "the test split",
                    mocap_garments(o, bench_file_exists(o->fnopt_model)),
                    o->mocap_frames, mocap_link);
            fprintf(f, "| method | cells | garments lost | inside_body %% | ms/frame |\n|---|---|---|---|---|\n");
        } else if (fn) {
            fprintf(f, "FNOpt grid scenes (`weft fnopt run --gt`), error = e3D relative to the XPBD reference of the "
                       "scene (not MVE; not comparable with the other panels).\n\n");
            fprintf(f, "| method | scenes | frames | e3D | ms/frame | diverged | note |\n|---|---|---|---|---|---|---|\n");
        } else {
            fprintf(f, "| method | CCD | sequences | frames | MVE (cm) | ms/frame | collision %% | self-collision %% | "
                       "max edge strain | NaN | exploded | note |\n"
                       "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
        }
        /* rows of this scenario sorted by ms/frame (selection, the tables are tiny) */
        bool done[CHART_MAX_METHODS * CHART_MAX_SCEN] = {false};
        for (;;) {
            size_t best = nrows;
            double best_ms = INFINITY;
            for (size_t i = 0; i < nrows; ++i) {
                if (done[i] || strcmp(rows[i].scenario, sc) != 0) {
                    continue;
                }
                double ms = rows[i].frames ? rows[i].ms_w / rows[i].frames : INFINITY;
                if (best == nrows || ms < best_ms) {
                    best = i;
                    best_ms = ms;
                }
            }
            if (best == nrows) {
                break;
            }
            done[best] = true;
            const chart_row *r = &rows[best];
            const chart_method *m = &methods[r->method];
            double w = r->frames ? (double)r->frames : NAN;
            const char *b = r->pareto ? "**" : "";
            if (mo) {
                fprintf(f, "| %s%s%s | %u | %u | %.2f | %.3f |\n", b, m->label, b, r->sequences, r->lost,
                        r->inside_w / w, r->ms_w / w);
            } else if (fn) {
                fprintf(f, "| %s%s%s | %u | %u | %.4f | %.3f | %u | %s |\n", b, m->label, b, r->sequences, r->frames,
                        r->e3d_w / w, r->ms_w / w, r->nan_runs, r->note);
            } else {
                fprintf(f, "| %s%s%s | %s | %u | %u | %.3f | %.3f | %.2f | %.2f | %.3f | %u | %u | %s |\n", b,
                        m->label, b, m->ccd ? "on" : "off", r->sequences, r->frames, r->mve_w / w, r->ms_w / w,
                        r->coll_w / w, r->self_w / w, r->max_strain, r->nan_runs, r->exploded_runs, r->note);
            }
        }
        fprintf(f, "\n");
    }
    if (nskipped) {
        fprintf(f, "## Not measured in this run\n\n");
        for (size_t i = 0; i < nskipped; ++i) {
            fprintf(f, "- %s\n", skipped[i]);
        }
        fprintf(f, "\n");
    }
    bench_link(o->out, o->csv_dir, "chart.csv", link, sizeof link);
    fprintf(f, "Raw numbers: [chart.csv](%s). Chart drawn by `tools/bench/plot_chart.py`.\n", link);
    fclose(f);

    return !o->plot || bench_plot(exe, "chart", "plot_chart.py", o->out, csv, "chart");
}

int weft_bench_chart(int argc, char **argv)
{
    chart_opts o = {.split = "test", .models = "tools/train/models", .out = "docs",
                    .fnopt_model = "tools/fnopt/models/fnopt_32.safetensors", .plot = true, .fnopt = true,
                    .mocap = true};
    char command[2048];
    bench_command_line(command, sizeof command, "weft bench chart", argc, argv);
    cli_parser cli;
    cli_start(&cli, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&cli, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        switch (id) {
        case CLI_STOP:
            return cli.exit;
        case OPT_QUICK:
            o.quick = true;
            break;
        case OPT_NO_PLOT:
            o.plot = false;
            break;
        case OPT_NO_FNOPT:
            o.fnopt = false;
            break;
        case OPT_XPBD:
        case OPT_XPBD_FAST: {
            const bool fast = id == OPT_XPBD_FAST;
            if (!bench_parse_substeps("chart", a, v, fast ? o.xpbd_fast : o.xpbd, 8, fast ? &o.nxpbd_fast : &o.nxpbd)) {
                return 2;
            }
            break;
        }
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
        case OPT_FNOPT_MODEL:
            o.fnopt_model = v;
            break;
        case OPT_FNOPT_MOTIONS:
            o.fnopt_motions = v;
            break;
        case OPT_NO_MOCAP:
            o.mocap = false;
            break;
        case OPT_MOCAP_FRAMES:
            if (!bench_parse_u32("chart", a, v, 1, 100000, &o.mocap_frames)) {
                return 2;
            }
            break;
        case OPT_MOCAP_CLIPS:
            o.mocap_clips = v;
            break;
        case OPT_MOCAP_GARMENTS:
            o.mocap_garments = v;
            break;
        case OPT_FRAMES:
        case OPT_MAX_SEQS:
            if (!bench_parse_u32("chart", a, v, 0, 1000000, id == OPT_FRAMES ? &o.frames : &o.max_seqs)) {
                return 2;
            }
            o.frames_given = o.frames_given || id == OPT_FRAMES;
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&cli) != 0) {
        return 2;
    }
    if (!o.data) {
        return cli_fail(&k_command, "--data is required");
    }
    o.csv_dir = bench_csv_dir(o.csv_dir, o.out, BENCH_DOCS_DATA_DIR);
    if (o.quick) {
        o.frames = o.frames ? o.frames : 30;
        o.max_seqs = o.max_seqs ? o.max_seqs : 2;
        o.mocap_frames = o.mocap_frames ? o.mocap_frames : 30;
        o.mocap_clips = o.mocap_clips ? o.mocap_clips : "walk_cmu07_01";
    }
    o.mocap_frames = o.mocap_frames ? o.mocap_frames : 150;
    char exe[1024];
    bench_seq *seqs = NULL;
    size_t nseq = 0;
    if (!bench_start("chart", o.data, o.split, o.out, exe, sizeof exe, &seqs, &nseq)) {
        return 1;
    }
    read_loadavg(chart_load_start, sizeof chart_load_start);

    static chart_method methods[CHART_MAX_METHODS];
    static char skipped[64][300];
    size_t nm = 0, nskipped = 0;
    memset(methods, 0, sizeof methods);
    chart_method *m = &methods[nm++];
    snprintf(m->label, sizeof m->label, "LBS");
    snprintf(m->family, sizeof m->family, "lbs");
    snprintf(m->method, sizeof m->method, "lbs");
    snprintf(m->precision, sizeof m->precision, "-");
    m->ccd = true;
    m = &methods[nm++];
    *m = methods[0];
    snprintf(m->label, sizeof m->label, "LBS no-CCD");
    m->ccd = false;
    /* Worn garments: LBS with the strain limit the learned rows get below (it mends LBS's own
     * stretched skinning too, so the comparison stays fair). */
    m = &methods[nm++];
    *m = methods[0];
    snprintf(m->label, sizeof m->label, "LBS + strain 10%%");
    snprintf(m->strain_pct, sizeof m->strain_pct, "10");
    m->garment_only = true;
    if (o.nxpbd == 0) {
        static const unsigned k_substeps[] = {5, 10, 20, 40};
        memcpy(o.xpbd, k_substeps, sizeof k_substeps);
        o.nxpbd = 4;
    }
    for (size_t k = 0; k < o.nxpbd; ++k) {
        m = &methods[nm++];
        snprintf(m->label, sizeof m->label, "XPBD-%u", o.xpbd[k]);
        snprintf(m->family, sizeof m->family, "xpbd");
        snprintf(m->method, sizeof m->method, "xpbd:%u", o.xpbd[k]);
        snprintf(m->precision, sizeof m->precision, "-");
        m->ccd = true;
    }
    /* Worn garments: the game-engine remedy for drift (tethers to the skinned garment, 3 cm) on the
     * cheapest XPBD and, below, on each model in int8 (the render sample's default). */
    m = &methods[nm++];
    *m = methods[nm - 1 - o.nxpbd]; /* XPBD at the first substep count */
    snprintf(m->label, sizeof m->label, "XPBD-%u + tethers 3 cm", o.xpbd[0]);
    snprintf(m->tether_cm, sizeof m->tether_cm, "3");
    m->garment_only = true;
    /* Every scene: the cheapest XPBD with the contact-aware strain limit, the strongest classical
     * baseline of docs/data/heldout_test_contact.md. */
    m = &methods[nm++];
    *m = methods[nm - 2 - o.nxpbd];
    snprintf(m->label, sizeof m->label, "XPBD-%u + strain 10%% + contact 1 cm", o.xpbd[0]);
    snprintf(m->strain_pct, sizeof m->strain_pct, "10");
    snprintf(m->strain_contact_cm, sizeof m->strain_contact_cm, "1");
    /* The fast XPBD (a game's collision projection instead of the bounds): CCD off at every count,
     * as a game runs it, and CCD on at the first. */
    if (o.nxpbd_fast == 0) {
        static const unsigned k_fast[] = {5, 10, 20, 40};
        memcpy(o.xpbd_fast, k_fast, sizeof k_fast);
        o.nxpbd_fast = 4;
    }
    for (size_t k = 0; k <= o.nxpbd_fast; ++k) {
        const unsigned S = o.xpbd_fast[k < o.nxpbd_fast ? k : 0];
        m = &methods[nm++];
        m->ccd = k == o.nxpbd_fast;
        snprintf(m->label, sizeof m->label, "XPBD-fast-%u%s", S, m->ccd ? "" : " no-CCD");
        snprintf(m->family, sizeof m->family, "xpbd-fast");
        snprintf(m->method, sizeof m->method, "xpbd-fast:%u", S);
        snprintf(m->precision, sizeof m->precision, "-");
    }
    static char model_names[32][256];
    size_t nmodels = bench_list_models(o.models, model_names, 32);
    if (nmodels == 0) {
        snprintf(skipped[nskipped++], 300, "learned models: no `*.safetensors` under `%s` yet", o.models);
    }
    static const char *const k_prec[] = {"fp32", "fp16", "int8"};
    for (size_t i = 0; i < nmodels && nm + 9 <= CHART_MAX_METHODS - 8; ++i) {
        char stem[256];
        snprintf(stem, sizeof stem, "%s", model_names[i]);
        stem[strlen(stem) - 12] = '\0';
        for (int p = 0; p < 3; ++p) {
            for (int c = 1; c >= 0; --c) {
                m = &methods[nm++];
                snprintf(m->label, sizeof m->label, "%.60s %s%s", stem, k_prec[p], c ? "" : " no-CCD");
                snprintf(m->family, sizeof m->family, "model");
                snprintf(m->method, sizeof m->method, "model");
                snprintf(m->precision, sizeof m->precision, "%s", k_prec[p]);
                bench_model_file(o.models, stem, model_names[i], k_prec[p], m->model, sizeof m->model);
                m->ccd = c != 0;
            }
        }
        m = &methods[nm++];
        *m = methods[nm - 3]; /* int8 with CCD */
        snprintf(m->label, sizeof m->label, "%.60s int8 + tethers 3 cm", stem);
        snprintf(m->tether_cm, sizeof m->tether_cm, "3");
        m->garment_only = true;
        /* ... and with the 10 % strain limit: the render sample's default (docs/MODEL.md). */
        m = &methods[nm++];
        *m = methods[nm - 2];
        snprintf(m->label, sizeof m->label, "%.60s int8 + tethers 3 cm + strain 10%%", stem);
        snprintf(m->strain_pct, sizeof m->strain_pct, "10");
        /* Every scene: int8 with the strain limit and the collider push, which hands CCD a frame
         * the collider does not cut (docs/CCD.md, *Collider push*). */
        m = &methods[nm++];
        *m = methods[nm - 5]; /* int8 with CCD */
        snprintf(m->label, sizeof m->label, "%.60s int8 + strain 10%% + push 1 cm", stem);
        snprintf(m->strain_pct, sizeof m->strain_pct, "10");
        snprintf(m->push_cm, sizeof m->push_cm, "1");
    }
    size_t first_fnopt = nm;
    static const char *const k_fnopt_opt[] = {"learned", "gd", "adam", "lbfgs"};
    if (o.fnopt) {
        for (int k = 0; k < 4; ++k) {
            if (k == 0 && !bench_file_exists(o.fnopt_model)) {
                snprintf(skipped[nskipped++], 300, "FNOpt learned optimizer: no weights at `%s`", o.fnopt_model);
                continue;
            }
            m = &methods[nm++];
            snprintf(m->label, sizeof m->label, k == 0 ? "FNOpt" : "%s (10 it)", k_fnopt_opt[k]);
            snprintf(m->family, sizeof m->family, "fnopt");
            snprintf(m->method, sizeof m->method, "%s", k_fnopt_opt[k]);
            snprintf(m->precision, sizeof m->precision, "fp32");
            snprintf(m->model, sizeof m->model, "%s", o.fnopt_model);
        }
    } else {
        snprintf(skipped[nskipped++], 300, "FNOpt grid scenes: disabled with --no-fnopt");
    }

    static chart_row rows[CHART_MAX_METHODS * CHART_MAX_SCEN];
    size_t nrows = 0;
    const size_t row_cap = sizeof rows / sizeof rows[0];
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    char frames_arg[16];
    snprintf(frames_arg, sizeof frames_arg, "%u", o.frames);
    /* Sequences per scenario used so far (for --max-seqs). */
    char scen_names[CHART_MAX_SCEN][32];
    uint32_t scen_used[CHART_MAX_SCEN] = {0};
    size_t nscen = 0;
    for (size_t s = 0; s < nseq; ++s) {
        size_t si = 0;
        while (si < nscen && strcmp(scen_names[si], seqs[s].scenario) != 0) {
            ++si;
        }
        if (si == nscen) {
            if (nscen == CHART_MAX_SCEN) {
                continue;
            }
            snprintf(scen_names[nscen++], 32, "%s", seqs[s].scenario);
        }
        if (o.max_seqs && scen_used[si] >= o.max_seqs) {
            continue;
        }
        scen_used[si]++;
        for (size_t k = 0; k < first_fnopt; ++k) {
            const chart_method *mm = &methods[k];
            if (mm->garment_only && strcmp(seqs[s].scenario, "garment") != 0) {
                continue;
            }
            chart_row *r = find_row(rows, &nrows, row_cap, seqs[s].scenario, (int)k);
            if (!r) {
                continue;
            }
            const bool is_model = strcmp(mm->family, "model") == 0;
            const bench_method_spec spec = {mm->method,
                                            mm->ccd,
                                            o.frames ? frames_arg : NULL,
                                            is_model ? mm->model : NULL,
                                            is_model ? mm->precision : NULL,
                                            mm->tether_cm,
                                            mm->strain_pct,
                                            mm->strain_contact_cm,
                                            mm->push_cm};
            const char *extra[24];
            bench_method_args(&spec, extra, 0);
            bench_eval_result e;
            bench_eval(exe, seqs[s].dir, extra, &e);
            r->sequences++;
            if (!e.ok) {
                /* A run that did not finish scores nothing: the benchmark stops here and writes
                 * no table or figure from partial results. */
                fprintf(stderr, "weft bench chart: %s on %s failed: %s; nothing written\n", mm->label, seqs[s].name,
                        e.why);
                free(seqs);
                return 1;
            }
            double w = e.frames;
            r->frames += e.frames;
            r->mve_w += e.mve_cm * w;
            r->coll_w += e.collision_rate * w;
            r->self_w += e.self_collision_rate * w;
            r->ms_w += e.ms_per_frame * w;
            r->max_strain = fmax(r->max_strain, e.max_edge_strain);
            r->nan_runs += e.nan;
            /* As the stability suite: over 1 % of the edges strained more than 25 % in some frame (one
             * such edge at a pin or a tight contact is common, in the reference too). */
            r->exploded_runs += e.overstretched_pct > 1.0;
            printf("%-24s %-22s frames %4u  MVE %8.3f cm  %8.3f ms/frame  coll %5.2f%%  strain %.3f%s\n",
                   seqs[s].name, mm->label, e.frames, e.mve_cm, e.ms_per_frame, e.collision_rate, e.max_edge_strain,
                   e.nan ? "  NaN" : "");
            fflush(stdout);
        }
    }
    if (o.fnopt && nm > first_fnopt) {
        /* Comma-separated motion names of `weft fnopt run --motion`. */
        char motions[256];
        snprintf(motions, sizeof motions, "%s", o.fnopt_motions ? o.fnopt_motions : (o.quick ? "xy" : "xy,xyz,rot_h0"));
        for (size_t k = first_fnopt; k < nm; ++k) {
            chart_row *r = find_row(rows, &nrows, row_cap, "fnopt-grid", (int)k);
            for (char *mo = motions; r && *mo;) {
                char *comma = strchr(mo, ',');
                char one[64];
                size_t len = comma ? (size_t)(comma - mo) : strlen(mo);
                snprintf(one, sizeof one, "%.*s", (int)(len < 63 ? len : 63), mo);
                if (!run_fnopt(exe, &o, &methods[k], one, r)) {
                    fprintf(stderr, "weft bench chart: FNOpt %s on %s failed: %s; nothing written\n",
                            methods[k].label, one, r->note);
                    free(seqs);
                    return 1;
                }
                printf("fnopt %-8s %-18s ok\n", one, methods[k].label);
                fflush(stdout);
                mo = comma ? comma + 1 : mo + len;
            }
        }
    }
    char cells_part[1200], cells_csv[1100];
    snprintf(cells_csv, sizeof cells_csv, "%s/chart_mocap.csv", o.csv_dir);
    snprintf(cells_part, sizeof cells_part, "%s.part", cells_csv);
    if (o.mocap) {
        char why_skipped[300] = "";
        if (!bench_mkdirs(o.csv_dir) ||
            !run_mocap(exe, &o, cells_part, methods, &nm, rows, &nrows, row_cap, why_skipped, sizeof why_skipped)) {
            remove(cells_part);
            free(seqs);
            return 1;
        }
        if (why_skipped[0] && nskipped < 64) {
            snprintf(skipped[nskipped++], 300, "%s", why_skipped);
        }
    } else {
        snprintf(skipped[nskipped++], 300, "real motion: disabled with --no-mocap");
    }
    /* Pareto front per scenario: no other valid row is at least as fast and as accurate, and
     * strictly better in one. */
    for (size_t i = 0; i < nrows; ++i) {
        const chart_method *mi = &methods[rows[i].method];
        if (!row_valid(&rows[i], mi)) {
            continue;
        }
        double ei = row_error(&rows[i], mi), ti = rows[i].ms_w / rows[i].frames;
        bool dominated = false;
        for (size_t j = 0; j < nrows && !dominated; ++j) {
            const chart_method *mj = &methods[rows[j].method];
            if (j == i || strcmp(rows[i].scenario, rows[j].scenario) != 0 || !row_valid(&rows[j], mj)) {
                continue;
            }
            double ej = row_error(&rows[j], mj), tj = rows[j].ms_w / rows[j].frames;
            dominated = ej <= ei && tj <= ti && (ej < ei || tj < ti);
        }
        rows[i].pareto = !dominated;
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double wall = (double)(t1.tv_sec - t0.tv_sec) + (double)(t1.tv_nsec - t0.tv_nsec) * 1e-9;
    if (!write_outputs(&o, methods, rows, nrows, skipped, nskipped, command, wall, exe) ||
        (o.mocap && rename(cells_part, cells_csv) != 0)) {
        remove(cells_part);
        free(seqs);
        return 1;
    }
    printf("wrote %s/chart.csv and %s/CHART.md (%zu rows, %.1f s)\n", o.csv_dir, o.out, nrows, wall);
    free(seqs);
    return 0;
}
