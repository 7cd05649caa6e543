/* `weft eval` options on the committed sample sequence: --sim-mesh with the sequence's own mesh
 * (an identity map) scores exactly as without it, --tether-cm runs and bad values of either fail
 * with an error exit. argv: weft binary, data folder, output folder. Exits 77 (skipped) without
 * a sample sequence. */
#define _POSIX_C_SOURCE 200809L /* posix_spawn, stat */
#include "test.h"

#include <fcntl.h>
#include <math.h>
#include <stdbool.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>

extern char **environ;

static const char *g_exe, *g_seq, *g_out;

/* Runs argv with stdout into `out_path`; returns the exit status (-1 if it did not exit). */
static int run_to(const char *const argv[], const char *out_path)
{
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, out_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    pid_t pid;
    int ok = posix_spawn(&pid, argv[0], &fa, NULL, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (ok != 0) {
        return -1;
    }
    int status = 0;
    if (waitpid(pid, &status, 0) < 0) {
        return -1;
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/* The JSON line eval printed, with its "ms_per_frame" value replaced by '#' (wall time differs per
 * run, in value and in length). */
static bool json_line(const char *path, char *out, size_t cap)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        return false;
    }
    bool found = false;
    char line[2048];
    while (fgets(line, sizeof line, f)) {
        if (line[0] == '{') {
            snprintf(out, cap, "%s", line);
            found = true;
        }
    }
    fclose(f);
    char *ms = found ? strstr(out, "\"ms_per_frame\": ") : NULL;
    if (ms) {
        char *value = ms + 16, *end = strchr(value, ',');
        if (end) {
            *value = '#';
            memmove(value + 1, end, strlen(end) + 1);
        }
    }
    return found;
}

static double json_number(const char *json, const char *key)
{
    char k[64];
    snprintf(k, sizeof k, "\"%s\": ", key);
    const char *p = strstr(json, k);
    return p ? strtod(p + strlen(k), NULL) : NAN;
}

static void sim_mesh_identity(void)
{
    char a[1200], b[1200], ja[2048], jb[2048];
    snprintf(a, sizeof a, "%s/eval_plain.txt", g_out);
    snprintf(b, sizeof b, "%s/eval_map.txt", g_out);
    const char *plain[] = {g_exe, "eval", "--seq", g_seq, "--method", "xpbd:5", "--frames", "6", "--json", NULL};
    const char *mapped[] = {g_exe,  "eval",   "--seq", g_seq,        "--method", "xpbd:5", "--frames",
                            "6",    "--json", "--sim-mesh", g_seq, NULL};
    CHECK_EQ_INT(run_to(plain, a), 0);
    CHECK_EQ_INT(run_to(mapped, b), 0);
    CHECK(json_line(a, ja, sizeof ja));
    CHECK(json_line(b, jb, sizeof jb));
    double mve = json_number(ja, "mve_cm");
    CHECK_MSG(isfinite(mve) && mve >= 0.0, "MVE '%s'", ja);
    CHECK_EQ_INT((int)json_number(ja, "frames"), 6);
    /* rest positions map onto themselves exactly, so the whole run is the same */
    CHECK_MSG(strcmp(ja, jb) == 0, "identity map changed the result:\n%s%s", ja, jb);
}

static void tethers_and_bad_values(void)
{
    char o[1200], j[2048];
    snprintf(o, sizeof o, "%s/eval_tether.txt", g_out);
    const char *tied[] = {g_exe, "eval", "--seq", g_seq, "--method", "xpbd:5", "--frames", "6", "--tether-cm", "2",
                          "--json", NULL};
    CHECK_EQ_INT(run_to(tied, o), 0);
    CHECK(json_line(o, j, sizeof j));
    CHECK_MSG(isfinite(json_number(j, "mve_cm")) && isfinite(json_number(j, "ccd_passes")), "%s", j);
    const char *negative[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--tether-cm", "-1", "--json", NULL};
    CHECK_EQ_INT(run_to(negative, o), 1); /* the library rejects the radius; nothing is scored */
    const char *garbage[] = {g_exe, "eval", "--seq", g_seq, "--tether-cm", "3cm", NULL};
    CHECK_EQ_INT(run_to(garbage, o), 2);
    const char *missing[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--sim-mesh", g_out, "--json", NULL};
    CHECK_EQ_INT(run_to(missing, o), 1); /* no rest_pos.npy there */
}

int main(int argc, char **argv)
{
    if (argc < 4) {
        fprintf(stderr, "usage: %s WEFT DATA OUT\n", argv[0]);
        return 1;
    }
    g_exe = argv[1];
    g_out = argv[3];
    static char seq[1024];
    snprintf(seq, sizeof seq, "%s/sample_seq", argv[2]);
    g_seq = seq;
    char meta[1100];
    struct stat st;
    snprintf(meta, sizeof meta, "%s/meta.json", seq);
    if (stat(meta, &st) != 0) {
        printf("no sample sequence at %s: skipped\n", meta);
        return 77;
    }
    mkdir(g_out, 0777);
    static const test_case_ cases[] = {TEST_CASE(sim_mesh_identity), TEST_CASE(tethers_and_bad_values)};
    return test_run_(cases, sizeof cases / sizeof cases[0], 1, argv);
}
