/* `weft simgen --avatar gltf:PATH --garment obj:PATH` on a user's character (weft's avatar exported
 * with renamed joints by samples.character) makes one validated sequence that `weft eval` scores
 * with the wear measures; a garment not on the character, one option without the other and a
 * mix with --mocap are refused. argv: weft binary, output folder, the folder with the character
 * files (build/tests). */
#define _POSIX_C_SOURCE 200809L /* posix_spawn, stat */
#include "test.h"

#include "tool_run.h"

#include <stdbool.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

static const char *g_exe, *g_out, *g_files;
static char g_avatar[1100], g_garment[1100];

static void character_sequence_is_made_and_scored(void)
{
    char dir[1100], meta[1200], cloth[1200], json[1200];
    snprintf(dir, sizeof dir, "%s/character_character_renamed_character_tshirt", g_out);
    snprintf(meta, sizeof meta, "%s/meta.json", dir);
    snprintf(cloth, sizeof cloth, "%s/cloth_pos.npy", dir);
    snprintf(json, sizeof json, "%s/eval.json", g_out);
    remove(meta); /* a rerun generates again */
    const char *argv[] = {g_exe,      "simgen", "--out", g_out,          "--avatar", g_avatar, "--garment", g_garment,
                          "--frames", "6",      "--substeps", "10", "--max-substeps", "20", "--preroll", "16", NULL};
    CHECK_EQ_INT(tool_run(argv, NULL), 0);
    static char text[1 << 16];
    tool_slurp(meta, text, sizeof text);
    CHECK_MSG(strstr(text, "\"accepted\":\ttrue") != NULL, "not accepted: %.400s", text);
    CHECK(strstr(text, "\"character\":") != NULL);
    CHECK(strstr(text, "\"body_parts\":\ttrue") != NULL);
    struct stat st;
    CHECK_MSG(stat(cloth, &st) == 0 && st.st_size > 6 * 3 * 4 * 1000, "no cloth positions in %s", cloth);
    const char *eval[] = {g_exe, "eval", "--seq", dir, "--method", "lbs", "--ccd", "off", "--json", NULL};
    CHECK_EQ_INT(tool_run(eval, json), 0);
    tool_slurp(json, text, sizeof text);
    CHECK_MSG(strstr(text, "\"garments_lost\":") != NULL, "no wear measures in the eval: %.400s", text);
    CHECK(strstr(text, "\"garments_lost\":0") != NULL || strstr(text, "\"garments_lost\": 0") != NULL ||
          strstr(text, "\"garments_lost\":\t0") != NULL);
}

static void bad_input_is_refused(void)
{
    char err[1200], bad[1200], text[4096];
    snprintf(err, sizeof err, "%s/err.txt", g_out);
    const char *alone[] = {g_exe, "simgen", "--out", g_out, "--avatar", g_avatar, NULL};
    CHECK_EQ_INT(tool_run_err(alone, NULL, err), 2);
    tool_slurp(err, text, sizeof text);
    CHECK(strstr(text, "--avatar and --garment go together") != NULL);
    const char *mixed[] = {g_exe, "simgen", "--out", g_out, "--avatar", g_avatar, "--garment", g_garment,
                           "--mocap", "test", NULL};
    CHECK_EQ_INT(tool_run_err(mixed, NULL, err), 2);
    /* a garment far from the character: a triangle 5 m away */
    snprintf(bad, sizeof bad, "%s/far_garment.obj", g_out);
    FILE *f = fopen(bad, "wb");
    CHECK(f != NULL);
    if (f) {
        fputs("v 5 0 0\nv 6 0 0\nv 5 1 0\nf 1 2 3\n", f);
        fclose(f);
    }
    char spec[1300];
    snprintf(spec, sizeof spec, "obj:%s", bad);
    const char *far[] = {g_exe, "simgen", "--out", g_out, "--avatar", g_avatar, "--garment", spec, NULL};
    CHECK(tool_run_err(far, NULL, err) != 0);
    tool_slurp(err, text, sizeof text);
    CHECK_MSG(strstr(text, "--garment") != NULL && strstr(text, "far_garment.obj") != NULL,
              "the refusal does not name the garment: %s", text);
}

int main(int argc, char **argv)
{
    if (argc < 4) {
        fprintf(stderr, "usage: %s WEFT_BINARY OUT_DIR CHARACTER_DIR\n", argv[0]);
        return 2;
    }
    g_exe = argv[1];
    g_out = argv[2];
    g_files = argv[3];
    snprintf(g_avatar, sizeof g_avatar, "gltf:%s/character_renamed.gltf", g_files);
    snprintf(g_garment, sizeof g_garment, "obj:%s/character_tshirt.obj", g_files);
    mkdir(g_out, 0755);
    static const test_case_ cases[] = {TEST_CASE(character_sequence_is_made_and_scored),
                                         TEST_CASE(bad_input_is_refused)};
    return test_run_(cases, sizeof cases / sizeof cases[0], argc - 3, argv + 3);
}
