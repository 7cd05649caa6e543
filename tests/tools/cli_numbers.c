/* Every numeric option of the `weft` commands is a whole value in its documented range: a value
 * that is not a number, has trailing text, a sign or spaces, overflows, is NaN or infinite, or
 * lies outside the range is refused with the usage exit (2) and a message naming the option,
 * before the command does any work; and one good value per command, where running it is cheap,
 * is taken. The shared parsers (tools/weft/support_cli.c) are also called directly with every
 * spelling they must refuse. argv: weft binary, output folder. */
#define _POSIX_C_SOURCE 200809L /* posix_spawn, mkdir */
#include "test.h"

#include "support_cli.h"
#include "tool_run.h"

#include <stdbool.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *g_exe, *g_out;
static char g_stdout[1100], g_stderr[1100];

/* Values no whole-number option takes, and values no real-number option takes: all of them for
 * the first option of each command, trailing text for the others (each weft start costs tens of
 * milliseconds: the binary links the renderer). The spellings only a whole-string parse refuses
 * are checked on the parsers themselves (helpers). */
static const char *const k_whole_all[] = {"abc", "2x", "3.7", "-1", "99999999999999999999", "nan", "", NULL};
static const char *const k_whole_few[] = {"2x", NULL};
static const char *const k_real_all[] = {"abc", "2x", "nan", "inf", "1e999", "", NULL};
static const char *const k_real_few[] = {"2x", NULL};

/* Runs `weft <pre...> <option> <value> <post...>`: it must exit 2 and name `named` on stderr. */
static void refused_as(const char *const *pre, const char *option, const char *value, const char *const *post,
                       const char *named)
{
    const char *argv[32];
    size_t n = 0;
    argv[n++] = g_exe;
    for (size_t k = 0; pre && pre[k] && n < 26; ++k) {
        argv[n++] = pre[k];
    }
    argv[n++] = option;
    argv[n++] = value;
    for (size_t k = 0; post && post[k] && n < 31; ++k) {
        argv[n++] = post[k];
    }
    argv[n] = NULL;
    const int rc = tool_run_err(argv, g_stdout, g_stderr);
    static char text[8192];
    tool_slurp(g_stderr, text, sizeof text);
    CHECK_MSG(rc == 2 && strstr(text, named) != NULL, "weft %s ... %s '%s': exit %d, stderr: %.300s", pre ? pre[0] : "",
              option, value, rc, text);
}

static void refused(const char *const *pre, const char *option, const char *value)
{
    refused_as(pre, option, value, NULL, option);
}

/* Every value of the generic list (NULL: none) and of `extra` (NULL-terminated) is refused. */
static void refuses_all(const char *const *pre, const char *option, const char *const *generic,
                        const char *const *extra)
{
    for (size_t k = 0; generic && generic[k]; ++k) {
        refused(pre, option, generic[k]);
    }
    for (size_t k = 0; extra && extra[k]; ++k) {
        refused(pre, option, extra[k]);
    }
}

/* `weft <args...>` exits 0. */
static void accepted(const char *const *args)
{
    const char *argv[40];
    size_t n = 0;
    argv[n++] = g_exe;
    for (size_t k = 0; args[k] && n < 39; ++k) {
        argv[n++] = args[k];
    }
    argv[n] = NULL;
    const int rc = tool_run_err(argv, g_stdout, g_stderr);
    static char text[8192];
    tool_slurp(g_stderr, text, sizeof text);
    CHECK_MSG(rc == 0, "weft %s %s ...: exit %d, stderr: %.400s", args[0], args[1] ? args[1] : "", rc, text);
}

static bool exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* The parsers themselves (tools/weft/support_cli.c, built into this test): every spelling that is
 * not exactly a number in range is refused and leaves the output alone. Their messages, and
 * so this case's failures, go to a file while it runs; the failures are repeated afterwards. */
static int g_saved_stderr = -1;
static char g_helpers_err[1100];

static void quiet(bool on)
{
    fflush(stderr);
    if (on) {
        g_saved_stderr = dup(2);
        const int fd = open(g_helpers_err, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) {
            dup2(fd, 2);
            close(fd);
        }
        return;
    }
    if (g_saved_stderr >= 0) {
        dup2(g_saved_stderr, 2);
        close(g_saved_stderr);
        g_saved_stderr = -1;
    }
    FILE *f = fopen(g_helpers_err, "r");
    char line[1024];
    while (f && fgets(line, sizeof line, f)) {
        if (strstr(line, "CHECK failed")) {
            fputs(line, stderr);
        }
    }
    if (f) {
        fclose(f);
    }
}

static void helpers(void)
{
    quiet(true);
    static const char *const not_whole[] = {"", "abc", "2x", "3.7", "-1", "-0", "+5", " 5", "5 ", "0x10", "1e3",
                                            "99999999999999999999", "4294967296", "nan", "inf", "5\n", "1_000"};
    for (size_t k = 0; k < sizeof not_whole / sizeof not_whole[0]; ++k) {
        uint32_t u = 77;
        CHECK_MSG(!cli_u32("t", "--n", not_whole[k], 0, UINT32_MAX, &u) && u == 77, "'%s' -> %u", not_whole[k], u);
    }
    uint32_t u = 77;
    CHECK(!cli_u32("t", "--n", NULL, 0, 10, &u) && u == 77);
    CHECK(!cli_u32("t", "--n", "2", 3, 7, &u) && !cli_u32("t", "--n", "8", 3, 7, &u) && u == 77);
    CHECK(cli_u32("t", "--n", "3", 3, 7, &u) && u == 3 && cli_u32("t", "--n", "007", 3, 7, &u) && u == 7);
    CHECK(cli_u32("t", "--n", "4294967295", 0, UINT32_MAX, &u) && u == UINT32_MAX);
    uint64_t w = 77;
    CHECK(cli_u64("t", "--n", "18446744073709551615", 0, UINT64_MAX, &w) && w == UINT64_MAX);
    w = 77;
    CHECK(!cli_u64("t", "--n", "18446744073709551616", 0, UINT64_MAX, &w) && w == 77);

    static const char *const not_real[] = {"", "abc", "2x", "nan", "-nan", "inf", "-inf", "infinity", "1e39", "1e-50",
                                           " 1", "+1", "1 ", "0.5.5", "1,5", "-", ".", "-.", "0x", "1e", "-1", "11"};
    for (size_t k = 0; k < sizeof not_real / sizeof not_real[0]; ++k) {
        float f = 77.0f;
        double d = 77.0;
        CHECK_MSG(!cli_float("t", "--x", not_real[k], 0.0f, 10.0f, &f) && f == 77.0f, "'%s' -> %g", not_real[k],
                  (double)f);
        if (strcmp(not_real[k], "1e39") != 0 && strcmp(not_real[k], "1e-50") != 0) { /* doubles in range */
            CHECK_MSG(!cli_double("t", "--x", not_real[k], 0.0, 10.0, &d) && d == 77.0, "'%s' -> %g", not_real[k], d);
        }
    }
    float f = 77.0f;
    CHECK(cli_float("t", "--x", ".5", 0.0f, 1.0f, &f) && f == 0.5f);
    CHECK(cli_float("t", "--x", "-0.25", -1.0f, 1.0f, &f) && f == -0.25f);
    CHECK(cli_float("t", "--x", "1e-3", 0.0f, 1.0f, &f) && f == 1e-3f);
    CHECK(cli_float("t", "--x", "10", 0.0f, 10.0f, &f) && f == 10.0f);
    double d = 77.0;
    CHECK(!cli_double("t", "--x", "1e999", 0.0, 1e300, &d) && !cli_double("t", "--x", "1e-400", 0.0, 1.0, &d) &&
          d == 77.0);
    CHECK(cli_double("t", "--x", "0.001", 0.001, 1e6, &d) && d == 0.001);
    CHECK(cli_double("t", "--x", "1e-50", 0.0, 1.0, &d) && d == 1e-50);

    uint32_t list[8] = {0};
    size_t n = 99;
    CHECK(cli_u32_list("t", "--l", "5", 1, 1000, list, 8, &n) && n == 1 && list[0] == 5);
    CHECK(cli_u32_list("t", "--l", "5,10,20", 1, 1000, list, 8, &n) && n == 3 && list[2] == 20);
    CHECK(cli_u32_list("t", "--l", "1,2,3,4,5,6,7,8", 1, 1000, list, 8, &n) && n == 8 && list[7] == 8);
    static const char *const not_list[] = {"", ",", "5,", ",5", "5,,6", "5;6", "5 ,6", "5, 6", "1,2,3,4,5,6,7,8,9",
                                           "0", "1001", "5,x", "5,-1", "3.7", "99999999999999999999"};
    for (size_t k = 0; k < sizeof not_list / sizeof not_list[0]; ++k) {
        n = 99;
        list[0] = 77;
        CHECK_MSG(!cli_u32_list("t", "--l", not_list[k], 1, 1000, list, 8, &n) && n == 99 && list[0] == 77, "'%s'",
                  not_list[k]);
    }
    float m[3] = {0};
    CHECK(cli_floats("t", "--m", "1000,8,0.5", 0.0f, 1e6f, m, 3) && m[0] == 1000.0f && m[2] == 0.5f);
    static const char *const not_three[] = {"", "1,2", "1,2,3,4", "1,,2,3", "1,2,3,", ",1,2,3", "1,2,nan",
                                            "1 ,2,3", "-1,2,3", "1,2,3x", "1e7,1,1"};
    for (size_t k = 0; k < sizeof not_three / sizeof not_three[0]; ++k) {
        m[0] = 77.0f;
        CHECK_MSG(!cli_floats("t", "--m", not_three[k], 0.0f, 1e6f, m, 3) && m[0] == 77.0f, "'%s'", not_three[k]);
    }
    quiet(false);
}

static void bench_body(void)
{
    const char *pre[] = {"bench", "body", NULL};
    refuses_all(pre, "--frames", k_whole_all, (const char *const[]){"0", "1000001", NULL});
    /* a good run builds every garment at every resolution: seconds, not run here */
}

static void bench_ccd(void)
{
    const char *pre[] = {"bench", "ccd", NULL};
    refuses_all(pre, "--queries", k_whole_all, (const char *const[]){"0", "10000001", NULL});
    refuses_all(pre, "--frames", k_whole_few, (const char *const[]){"0", "100001", NULL});
    accepted((const char *const[]){"bench", "ccd", "--queries", "1", "--frames", "1", NULL});
}

static void bench_fnopt(void)
{
    const char *pre[] = {"bench", "fnopt", NULL};
    refuses_all(pre, "--frames", k_whole_all, (const char *const[]){"100001", NULL});
    static const char *const lists[] = {"9", "1025", "32,", "32,,64", "32,6x", NULL};
    refuses_all(pre, "--res", k_whole_few, lists);
    refuses_all(pre, "--res", NULL, (const char *const[]){"10,10,10,10,10,10,10,10,10,10,10,10,10,10,10,10,10", NULL});
    refuses_all(pre, "--iters", k_whole_few, (const char *const[]){"0", "10001", "10,", "10,0", NULL});
    static const char *const material[] = {"1,2", "1,2,3,4", "-1,2,3", "1,2,nan", "1e7,1,1", NULL};
    refuses_all(pre, "--material", k_real_few, material);
    const char *model = WEFT_SOURCE_DIR "/tools/fnopt/models/fnopt_32.safetensors";
    if (exists(model)) {
        accepted((const char *const[]){"bench", "fnopt", "--model", model, "--res", "10", "--iters", "1,2", "--frames",
                                       "1", "--learned-only", "--material", "100,3,5", NULL});
    }
}

static void bench_xpbd(void)
{
    const char *pre[] = {"bench", "xpbd", NULL};
    refuses_all(pre, "--vertices", k_whole_all, (const char *const[]){"63", "200001", NULL});
    refuses_all(pre, "--frames", k_whole_few, (const char *const[]){"0", "100001", NULL});
    refuses_all(pre, "--only", k_whole_few, (const char *const[]){"0", "1001", NULL});
    refuses_all(pre, "--seed", k_whole_few, (const char *const[]){"18446744073709551616", NULL});
    accepted((const char *const[]){"bench", "xpbd", "--vertices", "64", "--frames", "1", "--only", "1", "--seed",
                                   "18446744073709551615", NULL});
}

static void bench_lod(void)
{
    const char *pre[] = {"bench", "lod", NULL};
    refuses_all(pre, "--push-cm", k_real_all, (const char *const[]){"0", "-1", "10.5", NULL});
    refuses_all(pre, "--tether-cm", k_real_few, (const char *const[]){"0", "-1", "1001", NULL});
    refuses_all(pre, "--strain-limit", k_real_few, (const char *const[]){"0", "1001", NULL});
    refuses_all(pre, "--frames", k_whole_few, (const char *const[]){"1000001", NULL});
    refuses_all(pre, "--max-seqs", k_whole_few, (const char *const[]){"1000001", NULL});
    refuses_all(pre, "--scale-frames", k_whole_few, (const char *const[]){"0", NULL});
    refuses_all(pre, "--xpbd", k_whole_few,
                (const char *const[]){"0", "1001", "5,,10", "5,10,", "1,2,3,4,5,6,7,8,9", NULL});
}

static void bench_model(void)
{
    const char *pre[] = {"bench", "model", NULL};
    refuses_all(pre, "--avatar-vertices", k_whole_all, (const char *const[]){"1999", "40001", NULL});
}

/* The other benchmarks' shared parsers (support_bench): the counts and the substep lists. */
static void bench_chart_and_stability(void)
{
    const char *chart[] = {"bench", "chart", NULL};
    refuses_all(chart, "--frames", k_whole_few, (const char *const[]){"1000001", NULL});
    refuses_all(chart, "--xpbd", k_whole_few, (const char *const[]){"0", "5,,10", "5,", NULL});
    refuses_all(chart, "--xpbd-fast", NULL, (const char *const[]){"abc", "1001", NULL});
    const char *stability[] = {"bench", "stability", NULL};
    refuses_all(stability, "--frames", k_whole_few, (const char *const[]){"0", NULL});
    refuses_all(stability, "--xpbd", NULL, (const char *const[]){"2x", "5,10,", NULL});
    const char *mocap[] = {"bench", "mocap", NULL};
    refuses_all(mocap, "--frames", k_whole_few, (const char *const[]){"100001", NULL});
}

static void ccd(void)
{
    char queries[1100], csv[1100];
    snprintf(queries, sizeof queries, "%s/one_query.txt", g_out);
    snprintf(csv, sizeof csv, "%s/bad_truth.csv", g_out);
    FILE *f = fopen(queries, "w");
    CHECK(f != NULL);
    if (f) {
        /* a vertex falling through a triangle */
        fputs("vf 0.25 1 0.25  0 0 0  1 0 0  0 0 1  0.25 -1 0.25  0 0 0  1 0 0  0 0 1\n", f);
        fclose(f);
    }
    const char *pre[] = {"ccd", "--queries", queries, NULL};
    refuses_all(pre, "--min-separation", k_real_all, (const char *const[]){"-0.1", "1.5", "0.1m", NULL});
    accepted((const char *const[]){"ccd", "--queries", queries, "--min-separation", "0.001", NULL});
    /* a ground truth that is not the digit 0 or 1 is an error of the file, not read as 0 */
    f = fopen(csv, "w");
    CHECK(f != NULL);
    if (f) {
        fputs("1,4,1,4,1,1,1x\n", f);
        fclose(f);
    }
    const char *argv[] = {g_exe, "ccd", "--csv", csv, "--type", "vf", NULL};
    CHECK_EQ_INT(tool_run_err(argv, g_stdout, g_stderr), 1);
    static char text[4096];
    tool_slurp(g_stderr, text, sizeof text);
    CHECK_MSG(strstr(text, "ground truth must be 0 or 1") != NULL, "%s", text);
}

static void fnopt(void)
{
    const char *pre[] = {"fnopt", "run", NULL};
    refuses_all(pre, "--res", k_whole_all, (const char *const[]){"9", "1025", NULL});
    refuses_all(pre, "--frames", k_whole_few, (const char *const[]){"100001", NULL});
    refuses_all(pre, "--iters", k_whole_few, (const char *const[]){"0", "10001", NULL});
    refuses_all(pre, "--speed", k_real_few, (const char *const[]){"0", "0.001", "101", NULL});
    refuses_all(pre, "--amplitude", k_real_few, (const char *const[]){"-0.5", "11", NULL});
    refuses_all(pre, "--lr", k_real_few, (const char *const[]){"0", "-1", "101", NULL});
    refuses_all(pre, "--repulsion", k_real_few, (const char *const[]){"-1", "1e7", NULL});
    refuses_all(pre, "--material", k_real_few, (const char *const[]){"1,2", "1,2,3,4", "1,2,x", "-1,2,3", NULL});
    accepted((const char *const[]){"fnopt", "run", "--res", "10", "--frames", "1", "--iters", "1", "--optimizer", "gd",
                                   "--speed", "2", "--amplitude", "0.2", "--lr", "0.05", "--repulsion", "0",
                                   "--material", "100,3,5", NULL});
}

static void quantize(void)
{
    char in[1100], out[1100];
    snprintf(in, sizeof in, "%s/tools/train/models/game.safetensors", WEFT_SOURCE_DIR);
    snprintf(out, sizeof out, "%s/game.fp16.safetensors", g_out);
    const char *pre[] = {"quantize", in, out, NULL};
    refuses_all(pre, "--min-dim", k_whole_all, (const char *const[]){"0", "1048577", NULL});
    refuses_all(pre, "--calib-frames", k_whole_few, (const char *const[]){"0", "16777217", NULL});
    refuses_all(pre, "--val-frames", k_whole_few, (const char *const[]){"16777217", NULL});
    refuses_all(pre, "--smoothquant", k_real_few, (const char *const[]){"-0.1", "1.1", NULL});
    refuses_all(pre, "--max-layer-error", k_real_few, (const char *const[]){"0", "-1", "1e7", NULL});
    if (exists(in)) {
        accepted((const char *const[]){"quantize", in, out, "--format", "fp16", "--no-val", "--min-dim", "16",
                                       "--val-frames", "0", "--max-layer-error", "0.05", NULL});
    }
}

static void eval(void)
{
    const char *pre[] = {"eval", "--seq", g_out, "--method", "lbs", NULL};
    refuses_all(pre, "--frames", k_whole_all, (const char *const[]){"0", "100000001", NULL});
    refuses_all(pre, "--ccd-iterations", k_whole_few, (const char *const[]){"0", "65", NULL});
    refuses_all(pre, "--max-collider-tokens", k_whole_few, (const char *const[]){"4294967296", NULL});
    refuses_all(pre, "--crop-cm", k_real_few, (const char *const[]){"-1", "10001", NULL});
    refuses_all(pre, "--tether-cm", k_real_few, (const char *const[]){"-1", "1001", NULL});
    refuses_all(pre, "--strain-limit", k_real_few, (const char *const[]){"-5", "1001", NULL});
    refuses_all(pre, "--strain-contact-cm", k_real_few, (const char *const[]){"-1", "101", NULL});
    refuses_all(pre, "--push-cm", k_real_few, (const char *const[]){"-1", "11", NULL});
    refuses_all(pre, "--push-depth-cm", k_real_few, (const char *const[]){"-1", "51", NULL});
    refuses_all(pre, "--time-limit", k_real_few, (const char *const[]){"0", "-1", "1000001", NULL});
    const char *seq[] = {"eval", "--seq", g_out, NULL};
    static const char *const methods[] = {"xpbd:", "xpbd:0", "xpbd:1001", "xpbd:5x", "xpbd-fast:-1", NULL};
    for (size_t k = 0; methods[k]; ++k) {
        refused_as(seq, "--method", methods[k], NULL, "--method");
    }
    /* the good values run on the sample sequence in tools.eval_options */
}

static void simgen(void)
{
    char dir[1100], good[1100];
    snprintf(dir, sizeof dir, "%s/simgen_refused", g_out);
    snprintf(good, sizeof good, "%s/simgen", g_out);
    const char *pre[] = {"simgen", "--out", dir, "--manifest-only", "--scenario", "drop", NULL};
    refuses_all(pre, "--checkpoint-frames", k_whole_all, (const char *const[]){"2.5", "100001", NULL});
    refuses_all(pre, "--time-limit", k_real_few, (const char *const[]){"-3", "1e10", NULL});
    refuses_all(pre, "--prefix-min", k_whole_all, (const char *const[]){"2.5", "100001", NULL});
    refuses_all(pre, "--speed", k_real_few, (const char *const[]){"0", "0.05", "11", NULL});
    refuses_all(pre, "--arm-spread", k_real_few, (const char *const[]){"-0.1", "0.9", NULL});
    refuses_all(pre, "--ease-in-retry", k_real_few, (const char *const[]){"2.5", NULL});
    refuses_all(pre, "--amplitude-retry", k_real_few, (const char *const[]){"0.05", "1.5", NULL});
    refuses_all(pre, "--vertices", k_whole_few, (const char *const[]){"2", "10000001", NULL});
    static const char *const shards[] = {"1/3x", "-1/3", "3/3", "1/0", "/3", "1", "1/200000", "1/ 3", NULL};
    refuses_all(pre, "--shard", NULL, shards);
    CHECK_MSG(!exists(dir), "a refused simgen created %s", dir);
    accepted((const char *const[]){"simgen", "--out", good, "--manifest-only", "--scenario", "drop", "--count", "2",
                                   "--vertices", "64", "--frames", "2", "--shard", "1/2", "--checkpoint-frames", "0",
                                   "--time-limit", "0", "--speed", "1.5", "--prefix-min", "0", NULL});
}

static void body(void)
{
    char obj[1100];
    snprintf(obj, sizeof obj, "%s/body.obj", g_out);
    const char *pre[] = {"body", NULL};
    const char *post[] = {"--obj", obj, NULL};
    static const char *const heights[] = {"2x", "nan", "-1", "101", NULL};
    for (size_t k = 0; heights[k]; ++k) {
        refused_as(pre, "--height", heights[k], post, "--height");
    }
}

#if CLI_NUMBERS_RENDER
static void bench_render(void)
{
    const char *pre[] = {"bench", "render", NULL};
    refuses_all(pre, "--size", k_whole_all, (const char *const[]){"15", "4097", NULL});
    refuses_all(pre, "--repeats", k_whole_few, (const char *const[]){"0", "10001", NULL});
    refuses_all(pre, "--supersample", k_whole_few, (const char *const[]){"0", "5", NULL});
    /* a good run renders every golden scene: seconds, not run here */
}

static void render(void)
{
    char sheet[1100], png[1100];
    snprintf(sheet, sizeof sheet, "%s/docs_sheet.png", g_out);
    snprintf(png, sizeof png, "%s/seq_sheet.png", g_out);
    const char *docs[] = {"render", "--docs-sheet", sheet, NULL};
    refuses_all(docs, "--tile", k_whole_all, (const char *const[]){"63", "1025", "200px", "200x200", NULL});
    CHECK_MSG(!exists(sheet), "a refused docs sheet was written");
    /* --seq: --tile is N or WxH; --columns, --yaw and --pitch are checked before anything is read */
    const char *seq[] = {"render", "--seq", g_out, "--sheet", png, NULL};
    refuses_all(seq, "--tile", k_whole_few,
                (const char *const[]){"63", "1025", "64x", "x64", "64x64x64", "64x63", "64X64", NULL});
    refuses_all(seq, "--columns", k_whole_few, (const char *const[]){"0", "33", NULL});
    refuses_all(seq, "--yaw", k_real_few, (const char *const[]){"361", "-361", NULL});
    refuses_all(seq, "--pitch", k_real_few, (const char *const[]){"86", "-86", NULL});
    const char *sample = WEFT_SOURCE_DIR "/tests/data/sample_seq";
    if (exists(sample)) {
        accepted((const char *const[]){"render", "--seq", sample, "--sheet", png, "--frames", "0", "--tile", "64x80",
                                       "--columns", "1", "--yaw", "-10.5", "--pitch", "5", "--no-caption", NULL});
    }
}
#endif

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: %s WEFT OUT\n", argv[0]);
        return 1;
    }
    g_exe = argv[1];
    g_out = argv[2];
    mkdir(g_out, 0777);
    snprintf(g_stdout, sizeof g_stdout, "%s/stdout.txt", g_out);
    snprintf(g_stderr, sizeof g_stderr, "%s/stderr.txt", g_out);
    snprintf(g_helpers_err, sizeof g_helpers_err, "%s/helpers.txt", g_out);
    static const test_case_ cases[] = {
        TEST_CASE(helpers),
        TEST_CASE(bench_body), TEST_CASE(bench_ccd),   TEST_CASE(bench_fnopt), TEST_CASE(bench_xpbd),
        TEST_CASE(bench_lod),  TEST_CASE(bench_model), TEST_CASE(bench_chart_and_stability),
        TEST_CASE(ccd),        TEST_CASE(fnopt),       TEST_CASE(quantize),    TEST_CASE(eval),
        TEST_CASE(simgen),     TEST_CASE(body),
#if CLI_NUMBERS_RENDER
        TEST_CASE(bench_render), TEST_CASE(render),
#endif
    };
    return test_run_(cases, sizeof cases / sizeof cases[0], argc - 2, argv + 2);
}
