/* Child-process and dataset helpers for the harness benchmarks. Each measured run is a separate
 * `weft eval` process so that one method crashing or exhausting memory costs one cell of the
 * table, not the whole run, and every figure comes from the same code path users run. */
#define _XOPEN_SOURCE 700 /* POSIX 2008 (posix_spawn, readlink, mkstemp, opendir) and realpath */
#include "support_bench.h"
#include "support_cli.h"
#include "weft/sim.h"

#include <cjson/cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

bool bench_self_exe(char *out, size_t cap)
{
    ssize_t n = readlink("/proc/self/exe", out, cap - 1);
    if (n <= 0 || (size_t)n >= cap - 1) {
        return false;
    }
    out[n] = '\0';
    return true;
}

char *bench_slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    char *p = NULL;
    if (fseek(f, 0, SEEK_END) == 0) {
        long n = ftell(f);
        if (n >= 0 && fseek(f, 0, SEEK_SET) == 0 && (p = malloc((size_t)n + 1)) != NULL) {
            if (fread(p, 1, (size_t)n, f) != (size_t)n) {
                free(p);
                p = NULL;
            } else {
                p[n] = '\0';
                if (size) {
                    *size = (size_t)n;
                }
            }
        }
    }
    fclose(f);
    return p;
}

bool bench_mkdirs(const char *path)
{
    char tmp[1024];
    size_t n = strlen(path);
    if (n == 0 || n >= sizeof tmp) {
        return false;
    }
    memcpy(tmp, path, n + 1);
    for (char *p = tmp + 1; *p; ++p) {
        if (*p == '/') {
            *p = '\0';
            if (mkdir(tmp, 0777) != 0 && errno != EEXIST) {
                return false;
            }
            *p = '/';
        }
    }
    struct stat st;
    return (mkdir(tmp, 0777) == 0 || errno == EEXIST) && stat(tmp, &st) == 0 && S_ISDIR(st.st_mode);
}

void bench_sanitize(char *s)
{
    for (; *s; ++s) {
        if (*s == ',' || *s == '|' || *s == '\n' || *s == '\r' || *s == '"') {
            *s = (*s == ',') ? ';' : ' ';
        }
    }
}

/* The last non-empty line of a text, trimmed, into why. */
static void last_line(const char *text, char *why, size_t cap)
{
    if (!why || cap == 0) {
        return;
    }
    why[0] = '\0';
    if (!text) {
        return;
    }
    const char *end = text + strlen(text);
    while (end > text && (end[-1] == '\n' || end[-1] == '\r' || end[-1] == ' ')) {
        --end;
    }
    const char *begin = end;
    while (begin > text && begin[-1] != '\n' && begin[-1] != '\r') {
        --begin;
    }
    size_t n = (size_t)(end - begin);
    if (n >= cap) {
        n = cap - 1;
    }
    memcpy(why, begin, n);
    why[n] = '\0';
}

int bench_spawn(const char *const argv[], char **out, char *why, size_t why_cap)
{
    *out = NULL;
    if (why && why_cap) {
        why[0] = '\0';
    }
    /* stderr goes to a temporary file: reading two pipes without poll() could deadlock. */
    char errpath[] = "/tmp/weft-bench-XXXXXX";
    int errfd = mkstemp(errpath);
    if (errfd < 0) {
        snprintf(why, why_cap, "cannot create a temporary file: %s", strerror(errno));
        return -1;
    }
    int fds[2];
    if (pipe(fds) != 0) {
        snprintf(why, why_cap, "pipe: %s", strerror(errno));
        close(errfd);
        unlink(errpath);
        return -1;
    }
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, fds[1], STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&fa, errfd, STDERR_FILENO);
    posix_spawn_file_actions_addclose(&fa, fds[0]);
    posix_spawn_file_actions_addclose(&fa, fds[1]);
    posix_spawn_file_actions_addclose(&fa, errfd);
    pid_t pid;
    int se = posix_spawn(&pid, argv[0], &fa, NULL, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    close(fds[1]);
    close(errfd);
    if (se != 0) {
        snprintf(why, why_cap, "cannot start %s: %s", argv[0], strerror(se));
        close(fds[0]);
        unlink(errpath);
        return -1;
    }
    size_t len = 0, cap = 4096;
    char *buf = malloc(cap);
    for (;;) {
        if (buf && len + 1 >= cap) {
            char *nb = realloc(buf, cap * 2);
            if (!nb) {
                free(buf);
                buf = NULL;
            } else {
                buf = nb;
                cap *= 2;
            }
        }
        char sink[4096];
        ssize_t n = buf ? read(fds[0], buf + len, cap - len - 1) : read(fds[0], sink, sizeof sink);
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n <= 0) {
            break;
        }
        if (buf) {
            len += (size_t)n;
        }
    }
    close(fds[0]);
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    char *err = bench_slurp(errpath, NULL);
    unlink(errpath);
    last_line(err, why, why_cap);
    free(err);
    if (buf) {
        buf[len] = '\0';
    }
    *out = buf;
    if (WIFSIGNALED(status)) {
        if (why && why_cap) {
            char tail[160];
            snprintf(tail, sizeof tail, "%s", why);
            snprintf(why, why_cap, "killed by signal %d%s%s", WTERMSIG(status), tail[0] ? ": " : "", tail);
        }
        return -1;
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static double json_num(const cJSON *o, const char *key, bool *ok)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    if (!cJSON_IsNumber(v)) {
        *ok = false;
        return NAN;
    }
    return v->valuedouble;
}

bool bench_eval(const char *exe, const char *seq_dir, const char *const extra[], bench_eval_result *r)
{
    memset(r, 0, sizeof *r);
    const char *argv[32];
    int n = 0;
    argv[n++] = exe;
    argv[n++] = "eval";
    argv[n++] = "--json";
    argv[n++] = "--seq";
    argv[n++] = seq_dir;
    for (int i = 0; extra && extra[i] && n < 31; ++i) {
        argv[n++] = extra[i];
    }
    argv[n] = NULL;
    char *out = NULL;
    int rc = bench_spawn(argv, &out, r->why, sizeof r->why);
    /* The JSON object is the last line that starts with '{'. */
    const char *js = NULL;
    for (const char *p = out; p && *p; p = strchr(p, '\n') ? strchr(p, '\n') + 1 : p + strlen(p)) {
        if (*p == '{') {
            js = p;
        }
    }
    cJSON *j = js ? cJSON_Parse(js) : NULL;
    bool ok = j != NULL;
    if (j) {
        /* A failed run (eval exits 1) has null error metrics: they become NaN here, never a score. */
        r->nan = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(j, "nan"));
        bool scored = true;
        r->mve_cm = json_num(j, "mve_cm", &scored);
        r->collision_rate = json_num(j, "collision_rate", &scored);
        r->self_collision_rate = json_num(j, "self_collision_rate", &scored);
        r->ms_per_frame = json_num(j, "ms_per_frame", &ok);
        r->max_edge_strain = json_num(j, "max_edge_strain", &scored);
        if (!scored) {
            r->mve_cm = r->collision_rate = r->self_collision_rate = r->max_edge_strain = NAN;
            ok = ok && r->nan; /* only a non-finite rollout is a measured failure */
        }
        bool strain_ok = true;
        r->overstretched_pct = json_num(j, "overstretched_pct", &strain_ok);
        r->gt_max_edge_strain = json_num(j, "gt_max_edge_strain", &strain_ok);
        if (!strain_ok) {
            r->overstretched_pct = r->gt_max_edge_strain = NAN;
            ok = ok && r->nan;
        }
        r->time_limited = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(j, "time_limited"));
        double f = json_num(j, "frames", &ok);
        r->frames = ok && f >= 0 && f < 4e9 ? (uint32_t)f : 0;
        cJSON_Delete(j);
    }
    free(out);
    /* eval exits 1 on a per-sequence error even after printing JSON; zero frames means nothing
     * was measured. A NaN rollout is a measured failure, not a harness error. */
    r->ok = ok && (rc == 0 || r->nan) && (r->frames > 0 || r->nan);
    if (!r->ok && !r->why[0]) {
        snprintf(r->why, sizeof r->why, "eval exited with %d and no result", rc);
    }
    bench_sanitize(r->why);
    return r->ok;
}


static int cmp_seq(const void *a, const void *b)
{
    return strcmp(((const bench_seq *)a)->name, ((const bench_seq *)b)->name);
}

static bool is_file(const char *dir, const char *name)
{
    char p[1200];
    struct stat st;
    int n = snprintf(p, sizeof p, "%s/%s", dir, name);
    return n > 0 && (size_t)n < sizeof p && stat(p, &st) == 0 && S_ISREG(st.st_mode);
}

void bench_command_line(char *out, size_t cap, const char *prefix, int argc, char **argv)
{
    snprintf(out, cap, "%s", prefix);
    for (int i = 1; i < argc; ++i) {
        size_t len = strlen(out);
        snprintf(out + len, cap - len, " %s", argv[i]);
    }
}

bool bench_parse_u32(const char *tool, const char *opt, const char *v, uint32_t lo, uint32_t hi, uint32_t *out)
{
    char name[64];
    snprintf(name, sizeof name, "weft bench %s", tool);
    return cli_u32(name, opt, v, lo, hi, out);
}

bool bench_list_sequences(const char *root, const char *split, bench_seq **out, size_t *count)
{
    *out = NULL;
    *count = 0;
    DIR *dh = opendir(root);
    if (!dh) {
        return false;
    }
    bench_seq *list = NULL;
    size_t n = 0, cap = 0;
    bool ok = true;
    struct dirent *de;
    while ((de = readdir(dh)) != NULL) {
        bench_seq s;
        memset(&s, 0, sizeof s);
        int dl = snprintf(s.dir, sizeof s.dir, "%s/%s", root, de->d_name);
        if (de->d_name[0] == '.' || strlen(de->d_name) >= sizeof s.name || dl <= 0 || (size_t)dl >= sizeof s.dir ||
            !is_file(s.dir, "meta.json") || !is_file(s.dir, "cloth_pos.npy")) {
            continue;
        }
        memcpy(s.name, de->d_name, strlen(de->d_name) + 1);
        char path[1200];
        snprintf(path, sizeof path, "%s/meta.json", s.dir);
        char *text = bench_slurp(path, NULL);
        cJSON *meta = text ? cJSON_Parse(text) : NULL;
        free(text);
        if (!meta) {
            fprintf(stderr, "weft bench: %s: unreadable meta.json, skipped\n", s.dir);
            continue;
        }
        const cJSON *sc = cJSON_GetObjectItemCaseSensitive(meta, "scenario");
        const cJSON *fr = cJSON_GetObjectItemCaseSensitive(meta, "frames");
        const cJSON *cl = cJSON_GetObjectItemCaseSensitive(meta, "cloth");
        const cJSON *vx = cl ? cJSON_GetObjectItemCaseSensitive(cl, "vertices") : NULL;
        snprintf(s.scenario, sizeof s.scenario, "%s", cJSON_IsString(sc) ? sc->valuestring : "unknown");
        bench_sanitize(s.scenario);
        s.frames = cJSON_IsNumber(fr) && fr->valuedouble > 0 ? (uint32_t)fr->valuedouble : 0;
        s.vertices = cJSON_IsNumber(vx) && vx->valuedouble > 0 ? (uint32_t)vx->valuedouble : 0;
        const bool keep = !split || strcmp(weft_sim_sequence_split(s.dir), split) == 0;
        cJSON_Delete(meta);
        if (!keep) {
            continue;
        }
        if (n == cap) {
            cap = cap ? cap * 2 : 32;
            bench_seq *nl = realloc(list, cap * sizeof *nl);
            if (!nl) {
                ok = false;
                break;
            }
            list = nl;
        }
        list[n++] = s;
    }
    closedir(dh);
    if (!ok) {
        free(list);
        return false;
    }
    if (n) {
        qsort(list, n, sizeof *list, cmp_seq);
    }
    *out = list;
    *count = n;
    return true;
}

/* ---- model files, scripts and options shared by the harnesses ---- */

static int cmp_cstr(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

bool bench_file_exists(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0 && S_ISREG(st.st_mode);
}

size_t bench_list_models(const char *dir, char names[][256], size_t cap)
{
    DIR *dh = dir ? opendir(dir) : NULL;
    if (!dh) {
        return 0;
    }
    char *tmp[64];
    size_t n = 0;
    struct dirent *de;
    while ((de = readdir(dh)) != NULL && n < cap && n < 64) {
        size_t l = strlen(de->d_name);
        /* MODEL.fp16/int8.safetensors are `weft quantize` outputs of MODEL.safetensors, not models
         * of their own: bench_model_file picks them per precision. */
        bool quantized = l > 17 && (strcmp(de->d_name + l - 17, ".fp16.safetensors") == 0 ||
                                    strcmp(de->d_name + l - 17, ".int8.safetensors") == 0);
        if (l > 12 && l < 200 && !quantized && strcmp(de->d_name + l - 12, ".safetensors") == 0) {
            tmp[n++] = strdup(de->d_name);
        }
    }
    closedir(dh);
    qsort(tmp, n, sizeof tmp[0], cmp_cstr);
    size_t k = 0;
    for (size_t i = 0; i < n; ++i) {
        if (tmp[i]) {
            snprintf(names[k++], 256, "%s", tmp[i]);
            free(tmp[i]);
        }
    }
    return k;
}

bool bench_find_script(const char *exe, const char *name, char *out, size_t cap)
{
    snprintf(out, cap, "tools/bench/%s", name);
    if (bench_file_exists(out)) {
        return true;
    }
    char dir[1024];
    snprintf(dir, sizeof dir, "%s", exe);
    for (int up = 0; up < 3; ++up) {
        char *s = strrchr(dir, '/');
        if (!s) {
            return false;
        }
        *s = '\0';
    }
    int n = snprintf(out, cap, "%s/tools/bench/%s", dir, name);
    return n > 0 && (size_t)n < cap && bench_file_exists(out);
}

void bench_model_file(const char *dir, const char *stem, const char *base, const char *precision, char *out,
                       size_t cap)
{
    snprintf(out, cap, "%.700s/%.200s.%.8s.safetensors", dir, stem, precision);
    if (strcmp(precision, "fp32") == 0 || !bench_file_exists(out)) {
        snprintf(out, cap, "%.700s/%.250s", dir, base);
    }
}

bool bench_parse_substeps(const char *tool, const char *opt, const char *v, unsigned *out, size_t cap, size_t *count)
{
    char name[64];
    uint32_t got[8];
    size_t n = 0;
    snprintf(name, sizeof name, "weft bench %s", tool);
    if (!cli_u32_list(name, opt, v, 1, 1000, got, cap < 8 ? cap : 8, &n)) {
        return false;
    }
    for (size_t k = 0; k < n; ++k) {
        out[k] = got[k];
    }
    *count = n;
    return true;
}

bool bench_start(const char *tool, const char *data, const char *split, const char *out, char *exe, size_t exe_cap,
                 bench_seq **seqs, size_t *nseq)
{
    *seqs = NULL;
    *nseq = 0;
    if (!bench_self_exe(exe, exe_cap)) {
        fprintf(stderr, "weft bench %s: cannot find the running weft binary (/proc/self/exe)\n", tool);
        return false;
    }
    if (!bench_mkdirs(out)) {
        fprintf(stderr, "weft bench %s: cannot create %s\n", tool, out);
        return false;
    }
    if (!bench_list_sequences(data, strcmp(split, "all") == 0 ? NULL : split, seqs, nseq)) {
        fprintf(stderr, "weft bench %s: cannot read %s\n", tool, data);
        return false;
    }
    if (*nseq == 0) {
        fprintf(stderr, "weft bench %s: no %s sequences (meta.json + cloth_pos.npy) under %s\n", tool, split, data);
        free(*seqs);
        *seqs = NULL;
        return false;
    }
    return true;
}

int bench_method_args(const bench_method_spec *spec, const char **out, int n)
{
    out[n++] = "--method";
    out[n++] = spec->method;
    out[n++] = "--ccd";
    out[n++] = spec->ccd ? "on" : "off";
    if (spec->frames && spec->frames[0]) {
        out[n++] = "--frames";
        out[n++] = spec->frames;
    }
    if (spec->model) {
        out[n++] = "--model";
        out[n++] = spec->model;
        out[n++] = "--precision";
        out[n++] = spec->precision;
    }
    if (spec->tether_cm && spec->tether_cm[0]) {
        out[n++] = "--tether-cm";
        out[n++] = spec->tether_cm;
    }
    if (spec->strain_pct && spec->strain_pct[0]) {
        out[n++] = "--strain-limit";
        out[n++] = spec->strain_pct;
    }
    if (spec->strain_contact_cm && spec->strain_contact_cm[0]) {
        out[n++] = "--strain-contact-cm";
        out[n++] = spec->strain_contact_cm;
    }
    if (spec->push_cm && spec->push_cm[0]) {
        out[n++] = "--push-cm";
        out[n++] = spec->push_cm;
    }
    if (strncmp(spec->method, "xpbd", 4) != 0) { /* XPBD solves with them already (same arguments as before) */
        out[n++] = "--pins";
        out[n++] = "all";
    }
    out[n] = NULL;
    return n;
}

bool bench_plot(const char *exe, const char *tool, const char *script, const char *out_dir, const char *csv,
                const char *name)
{
    char path[1200], png[1200], img[1200];
    snprintf(img, sizeof img, "%s/img", out_dir);
    snprintf(png, sizeof png, "%s/img/%s.png", out_dir, name);
    if (!bench_mkdirs(img) || !bench_find_script(exe, script, path, sizeof path)) {
        fprintf(stderr, "weft bench %s: tools/bench/%s not found (run from the source root); no PNG\n", tool, script);
        return false;
    }
    const char *argv[] = {"/usr/bin/python3", path, "--csv", csv, "--out", png, NULL};
    char *out = NULL, why[240];
    int rc = bench_spawn(argv, &out, why, sizeof why);
    free(out);
    if (rc != 0) {
        fprintf(stderr, "weft bench %s: plotting failed: %s\n", tool, why);
        return false;
    }
    printf("wrote %s\n", png);
    return true;
}

/* p without a leading "./" and trailing slashes equals "docs". */
static bool is_docs_dir(const char *p)
{
    while (p[0] == '.' && p[1] == '/') {
        p += 2;
    }
    size_t n = strlen(BENCH_DOCS_DIR);
    if (strncmp(p, BENCH_DOCS_DIR, n) != 0) {
        return false;
    }
    for (p += n; *p == '/'; ++p) {
    }
    return *p == '\0';
}

const char *bench_csv_dir(const char *given, const char *out, const char *data_dir)
{
    return given ? given : is_docs_dir(out) ? data_dir : out;
}

void bench_link(const char *from_dir, const char *to_dir, const char *name, char *out, size_t cap)
{
    char *from = realpath(from_dir, NULL), *to = realpath(to_dir, NULL);
    if (!from || !to) {
        snprintf(out, cap, "%s/%s", to_dir, name);
        free(from);
        free(to);
        return;
    }
    /* The longest common leading run of whole components. */
    size_t common = 0;
    for (size_t i = 0;; ++i) {
        const bool end_f = from[i] == '\0' || from[i] == '/', end_t = to[i] == '\0' || to[i] == '/';
        if (end_f && end_t) {
            common = i;
            if (from[i] == '\0' || to[i] == '\0') {
                break;
            }
        } else if (from[i] != to[i]) {
            break;
        }
    }
    size_t len = 0;
    out[0] = '\0';
    for (const char *p = from + common; *p && len < cap; ++p) { /* "../" per component of from below it */
        if (*p == '/' && p[1] != '\0') {
            len += (size_t)snprintf(out + len, cap - len, "../");
        }
    }
    const char *rest = to + common;
    rest += *rest == '/';
    if (*rest && len < cap) {
        len += (size_t)snprintf(out + len, cap - len, "%s/", rest);
    }
    if (len < cap) {
        snprintf(out + len, cap - len, "%s", name);
    }
    free(from);
    free(to);
}

char *bench_append(char *buf, size_t *len, size_t *cap, const char *s)
{
    size_t n = strlen(s);
    if (*len + n + 1 > *cap) {
        size_t nc = (*cap + n + 1) * 2;
        char *nb = realloc(buf, nc);
        if (!nb) {
            free(buf);
            return NULL;
        }
        buf = nb;
        *cap = nc;
    }
    memcpy(buf + *len, s, n + 1);
    *len += n;
    return buf;
}

char *bench_replace_block(char *doc, const char *tag, const char *body, const char *title)
{
    char open[96], close[96];
    snprintf(open, sizeof open, "<!-- %s -->", tag);
    snprintf(close, sizeof close, "<!-- /%s -->", tag);
    size_t len = 0, cap = 0;
    char *out = NULL;
    char *a = doc ? strstr(doc, open) : NULL;
    char *b = a ? strstr(a, close) : NULL;
    if (a && b) {
        char saved = *a;
        *a = '\0';
        out = bench_append(out, &len, &cap, doc);
        *a = saved;
        out = out ? bench_append(out, &len, &cap, open) : NULL;
        out = out ? bench_append(out, &len, &cap, "\n") : NULL;
        out = out ? bench_append(out, &len, &cap, body) : NULL;
        out = out ? bench_append(out, &len, &cap, b) : NULL;
    } else {
        out = bench_append(out, &len, &cap, doc ? doc : title);
        out = out ? bench_append(out, &len, &cap, "\n") : NULL;
        out = out ? bench_append(out, &len, &cap, open) : NULL;
        out = out ? bench_append(out, &len, &cap, "\n") : NULL;
        out = out ? bench_append(out, &len, &cap, body) : NULL;
        out = out ? bench_append(out, &len, &cap, close) : NULL;
        out = out ? bench_append(out, &len, &cap, "\n") : NULL;
    }
    free(doc);
    return out;
}

bool bench_write_doc(const char *tool, const char *path, char *doc)
{
    FILE *f = doc ? fopen(path, "w") : NULL;
    bool wrote = f && fputs(doc, f) >= 0;
    if (f) {
        wrote = fclose(f) == 0 && wrote;
    }
    free(doc);
    if (!wrote) {
        fprintf(stderr, "weft bench %s: cannot write %s\n", tool, path);
    } else {
        printf("wrote %s\n", path);
    }
    return wrote;
}

bool bench_ct_layer_per_step(const char *name)
{
    return strncmp(name, "dec_rest.", 9) != 0 && strcmp(name, "enc_xattn.q") != 0 && strcmp(name, "dec_xattn.q") != 0;
}
