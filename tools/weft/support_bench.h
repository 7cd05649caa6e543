/* Shared pieces of the harness benchmarks (`weft bench chart`, `weft bench stability`): running
 * other `weft` subcommands as child processes, reading their JSON, and walking simgen folders. */
#ifndef WEFT_SUPPORT_BENCH_H
#define WEFT_SUPPORT_BENCH_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* One `weft eval --json` run. ok is false when the child failed or printed no valid JSON; why
 * then holds its last stderr line (e.g. "unsupported: int8 needs ..."). */
typedef struct bench_eval_result {
    bool ok;
    double mve_cm, collision_rate, self_collision_rate, ms_per_frame, max_edge_strain;
    double overstretched_pct, gt_max_edge_strain; /* see cmd_eval.c */
    uint32_t frames;
    bool nan;
    bool time_limited; /* `--time-limit` stopped the rollout early */
    char why[240];
} bench_eval_result;

/* A simgen sequence folder. */
typedef struct bench_seq {
    char name[128];
    char dir[1024];
    char scenario[32];
    uint32_t frames, vertices;
} bench_seq;

/* Path of the running executable (/proc/self/exe); false when it cannot be read. */
bool bench_self_exe(char *out, size_t cap);

/* Runs argv (argv[0] is a path, argv NULL-terminated) with stdout captured into *out (malloc'd,
 * NUL-terminated; the caller frees) and the last non-empty stderr line copied into why.
 * Returns the exit status, or -1 when the child could not be started or was killed. */
int bench_spawn(const char *const argv[], char **out, char *why, size_t why_cap);

/* One method as `weft eval` arguments (see bench_method_args). */
typedef struct bench_method_spec {
    const char *method;                 /* lbs | xpbd:S | model */
    bool ccd;
    const char *frames;                 /* NULL or "": every frame */
    const char *model, *precision;      /* model methods only (NULL otherwise) */
    const char *tether_cm, *strain_pct; /* NULL or "": off */
    const char *strain_contact_cm;      /* NULL or "": the strain limit ignores the collider */
    const char *push_cm;                /* NULL or "": no collider push */
} bench_method_spec;

/* Appends spec's `weft eval` arguments (--method, --ccd, --frames, --model, --precision,
 * --tether-cm, --strain-limit, --strain-contact-cm, --push-cm, and `--pins all` for every method
 * but XPBD, which solves with the pins anyway: a scene's grasps and waistbands hold for every
 * method, as a game would set them; at most 20) to out at index n, NULL-terminates, and returns
 * the new count. out needs room for n + 21 entries. */
int bench_method_args(const bench_method_spec *spec, const char **out, int n);

/* `exe eval --json --seq seq_dir <extra...>` parsed into r. Returns r->ok. */
bool bench_eval(const char *exe, const char *seq_dir, const char *const extra[], bench_eval_result *r);

/* The whole file, NUL-terminated; NULL when it cannot be read. */
char *bench_slurp(const char *path, size_t *size);

/* Appends s to the growable string buf (length *len, capacity *cap); returns the new buffer, or
 * NULL (buf freed) when out of memory. */
char *bench_append(char *buf, size_t *len, size_t *cap, const char *s);

/* A generated block in a hand-written page: returns doc (freed) with the text between the lines
 * "<!-- TAG -->" and "<!-- /TAG -->" replaced by body, so the prose around it survives a rerun.
 * Without the markers the block is appended to doc (to title when doc is NULL: a new page).
 * NULL when out of memory. */
char *bench_replace_block(char *doc, const char *tag, const char *body, const char *title);

/* Writes doc (may be NULL: out of memory) to path and frees it; prints "wrote PATH", or a
 * "weft bench TOOL: cannot write" message and returns false. */
bool bench_write_doc(const char *tool, const char *path, char *doc);

/* mkdir -p. */
bool bench_mkdirs(const char *path);

/* Sequence folders (meta.json + cloth_pos.npy) directly under root, sorted by name, whose
 * split is `split` (NULL: all), by weft_sim_sequence_split as `weft eval` decides it. *out is malloc'd; the caller frees. */
bool bench_list_sequences(const char *root, const char *split, bench_seq **out, size_t *count);

/* The common start of a harness benchmark: the running binary's path into exe, the output
 * folder created, and the sequences of `split` ("all": every one) under data into *seqs
 * (malloc'd; the caller frees). Prints "weft bench <tool>: ..." and returns false on failure,
 * including when no sequence is found. */
bool bench_start(const char *tool, const char *data, const char *split, const char *out, char *exe, size_t exe_cap,
                 bench_seq **seqs, size_t *nseq);

/* The FNOpt energy's coefficients (Y, S, B in grid units) fitted to the reference simulator's
 * material by `weft fnopt fit` (docs/FNOPT.md, "Material fit"); every FNOpt scene of the
 * harness benchmarks runs with them, as the FNOpt evaluation tables do. */
#define BENCH_FNOPT_MATERIAL "100,3,5"

/* The command line as the docs quote it: prefix ("weft bench chart") and every argument after
 * argv[0], space-separated, cut to cap. */
void bench_command_line(char *out, size_t cap, const char *prefix, int argc, char **argv);

/* An option's unsigned value: all digits, within [lo, hi] (cli_u32 of support_cli.h). On failure
 * prints "weft bench <tool>: <opt> wants a whole number in [lo, hi], got 'v'" and returns false,
 * *out untouched. */
bool bench_parse_u32(const char *tool, const char *opt, const char *v, uint32_t lo, uint32_t hi, uint32_t *out);

/* Collapses a stderr line into something safe for one CSV / markdown cell. */
void bench_sanitize(char *s);

/* A regular file exists at p. */
bool bench_file_exists(const char *p);

/* Model files (*.safetensors) in dir, sorted; the quantiser's MODEL.fp16/int8.safetensors are
 * left out (bench_model_file picks them per precision). Returns the count (<= cap, <= 64). */
size_t bench_list_models(const char *dir, char names[][256], size_t cap);

/* A plotting script tools/bench/NAME: relative to the working directory, else to the binary
 * (build-x/bin/weft -> ../../tools/bench). */
bool bench_find_script(const char *exe, const char *name, char *out, size_t cap);

/* Draws OUT/img/NAME.png from the CSV at csv with tools/bench/SCRIPT (python3, matplotlib);
 * prints what it wrote, or "weft bench TOOL: ..." on stderr and returns false. */
bool bench_plot(const char *exe, const char *tool, const char *script, const char *out_dir, const char *csv,
                const char *name);

/* The page folder every harness benchmark writes by default (--out). */
#define BENCH_DOCS_DIR "docs"
/* Where the bench output data of the repository lives: the CSVs behind the pages of docs/. */
#define BENCH_DOCS_DATA_DIR "docs/data"

/* The folder a benchmark writes its CSV to: given (--csv-dir) when not NULL; else data_dir (the
 * repository's folder for it, e.g. docs/data) when out is the default docs folder ("docs",
 * "./docs", "docs/"); else out itself, beside the page, so that a run into another folder keeps
 * its outputs together and leaves the repository's data alone. */
const char *bench_csv_dir(const char *given, const char *out, const char *data_dir);

/* The path of file `name` in folder to_dir as a link from a page in folder from_dir (both must
 * exist): "name" when they are the same folder, "data/name" for a subfolder, "../x/name" ...;
 * to_dir/name as given when a folder cannot be resolved. */
void bench_link(const char *from_dir, const char *to_dir, const char *name, char *out, size_t cap);

/* The file for one precision: MODEL.<precision>.safetensors when the quantiser wrote one, else
 * MODEL.safetensors (base), which the runtime converts at garment creation. */
void bench_model_file(const char *dir, const char *stem, const char *base, const char *precision, char *out,
                      size_t cap);

/* Substep counts "5,10,20" of option opt into out: one to cap (at most 8) values, each 1..1000,
 * their number in *count. On a malformed list prints "weft bench <tool>: <opt> wants ..." (as
 * cli_u32_list) and returns false, out and *count untouched. */
bool bench_parse_substeps(const char *tool, const char *opt, const char *v, unsigned *out, size_t cap, size_t *count);

/* Whether the learned model's layer `name` (as the calibration observer names it) runs every
 * step; false for the layers a garment computes once at creation and the observer shows again
 * (the rest-shape decoder, the cross-attention query projections). */
bool bench_ct_layer_per_step(const char *name);

#endif
