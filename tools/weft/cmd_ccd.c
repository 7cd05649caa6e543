/* weft ccd --queries FILE (or --csv FILE --type vf|ee for the public benchmark format): runs the
 * narrow phase on external CCD queries. Each line is `vf` or `ee`
 * followed by 24 numbers: the 4 points at t = 0, then the same 4 at t = 1 (vf: the vertex, then the
 * triangle; ee: edge a's end points, then edge b's). Prints `1 t_c` or `0` per query; empty lines
 * and lines starting with '#' are skipped. A timing summary goes to stderr. */
#define _POSIX_C_SOURCE 200809L
#include "core/core.h"
#include "weft/ccd.h"

#include "support_cli.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char weft_cmd_ccd_help[] = "continuous collision queries: weft ccd --queries FILE (vf/ee + 24 numbers per line)";

enum { OPT_QUERIES = 1, OPT_CSV, OPT_TYPE, OPT_MIN_SEPARATION };

static const cli_option k_options[] = {
    {"queries", "FILE", OPT_QUERIES,
     "one query per line, `vf` or `ee` then 24 numbers (4 points at t=0, then\n"
     "at t=1); '-' reads stdin. Output: `1 t_c` (collision, earliest time) or\n"
     "`0` per query"},
    {"csv", "FILE", OPT_CSV,
     "the public CCD benchmark's rational format (8 rows per query:\n"
     "num_x,den_x,num_y,den_y,num_z,den_z,ground_truth); prints the same lines\n"
     "and a false-negative / false-positive summary against the ground truth\n"
     "on stderr"},
    {"type", "vf|ee", OPT_TYPE, "the kind of the --csv file's queries (needed with --csv)"},
    {"min-separation", "METRES", OPT_MIN_SEPARATION, "the gap kept between the primitives, 0..1 m (default 0)"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft ccd",
    .synopsis = "weft ccd --queries FILE [--min-separation METRES]\n"
                "weft ccd --csv FILE --type vf|ee [--min-separation METRES]",
    .about = "Runs the narrow phase on external continuous collision queries.",
    .options = k_options,
};

/* Exact when numerator and denominator are integers below 2^53 and the denominator is a power of
 * two; otherwise the double is rounded and the file's ground truth may not hold for it. */
static bool rational_to_double(const char *num, const char *den, double *out)
{
    char *e1 = NULL, *e2 = NULL;
    double n = strtod(num, &e1), d = strtod(den, &e2);
    *out = n / d;
    int exp;
    bool pow2 = d > 0.0 && frexp(d, &exp) == 0.5;
    return e1 != num && e2 != den && fabs(n) < 0x1p53 && n == floor(n) && d < 0x1p53 && pow2;
}

static int run_csv(const char *path, bool vf, double eta)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "weft ccd: cannot open '%s': %s\n", path, strerror(errno));
        return 1;
    }
    char line[1024];
    double q[24];
    int row = 0, gt = -1, status = 0;
    unsigned long lineno = 0, queries = 0, positives = 0, fn = 0, fp = 0, inexact = 0;
    bool query_inexact = false;
    double ms = 0.0;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        if (line[0] == '#' || line[0] == '\n' || line[0] == '\r' || line[0] == '\0') {
            continue;
        }
        char *field[7];
        int nf = 0;
        for (char *tok = strtok(line, ",\r\n"); tok && nf < 7; tok = strtok(NULL, ",\r\n")) {
            field[nf++] = tok;
        }
        if (nf != 7) {
            fprintf(stderr, "weft ccd: %s:%lu: expected 7 comma-separated fields\n", path, lineno);
            status = 1;
            break;
        }
        /* the ground truth is the digit 0 or 1 (spaces around it allowed), nothing else */
        const char *gtf = field[6] + strspn(field[6], " \t");
        const int g = (gtf[0] == '0' || gtf[0] == '1') && gtf[1 + strspn(gtf + 1, " \t")] == '\0' ? gtf[0] - '0' : -1;
        if (g < 0 || (row > 0 && g != gt)) {
            fprintf(stderr, "weft ccd: %s:%lu: ground truth must be 0 or 1 and equal on a query's 8 rows\n", path,
                    lineno);
            status = 1;
            break;
        }
        gt = g;
        /* Rows: the 4 points at t = 0, then at t = 1, as in the --queries order. */
        for (int k = 0; k < 3; ++k) {
            query_inexact |= !rational_to_double(field[2 * k], field[2 * k + 1], &q[3 * row + k]);
        }
        if (++row < 8) {
            continue;
        }
        double toi = 1.0;
        double t0 = weft__now_ms();
        int hit = vf ? weft_ccd_vertex_face(q, eta, &toi) : weft_ccd_edge_edge(q, eta, &toi);
        ms += weft__now_ms() - t0;
        if (hit) {
            printf("1 %.17g\n", toi);
        } else {
            printf("0\n");
        }
        queries++;
        positives += (unsigned long)gt;
        fn += (unsigned long)(gt && !hit);
        fp += (unsigned long)(!gt && hit);
        inexact += query_inexact;
        query_inexact = false;
        row = 0;
    }
    fclose(f);
    if (row != 0 && status == 0) {
        fprintf(stderr, "weft ccd: %s: %d trailing rows (a query is 8 rows)\n", path, row);
        status = 1;
    }
    fprintf(stderr, "weft ccd: %lu %s queries, %lu collide by the ground truth: %lu false negatives, %lu false "
                    "positives; %lu queries not exactly representable in double; %.4f us per query\n",
            queries, vf ? "vf" : "ee", positives, fn, fp, inexact, queries ? 1e3 * ms / (double)queries : 0.0);
    return status;
}

int weft_cmd_ccd(int argc, char **argv);
int weft_cmd_ccd(int argc, char **argv)
{
    const char *path = NULL, *csv = NULL, *type = NULL;
    double eta = 0.0;
    cli_parser cp;
    cli_start(&cp, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&cp, &v)) != CLI_END;) {
        switch (id) {
        case CLI_STOP:
            return cp.exit;
        case OPT_QUERIES:
            path = v;
            break;
        case OPT_CSV:
            csv = v;
            break;
        case OPT_TYPE:
            type = v;
            break;
        case OPT_MIN_SEPARATION:
            if (!cli_double(k_command.tool, cli_name(&k_command, id), v, 0.0, 1.0, &eta)) {
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
    if (csv) {
        if (!type || (strcmp(type, "vf") != 0 && strcmp(type, "ee") != 0)) {
            fprintf(stderr, "weft ccd: --csv needs --type vf or --type ee\n");
            return 2;
        }
        return run_csv(csv, strcmp(type, "vf") == 0, eta);
    }
    if (!path) {
        return cli_fail(&k_command, "--queries FILE or --csv FILE is required");
    }
    FILE *f = strcmp(path, "-") == 0 ? stdin : fopen(path, "r");
    if (!f) {
        fprintf(stderr, "weft ccd: cannot open '%s': %s\n", path, strerror(errno));
        return 1;
    }
    /* Parse everything first so the timing covers the narrow phase only. */
    char line[4096];
    unsigned long lineno = 0;
    size_t count = 0, cap = 0;
    double *q = NULL;
    unsigned char *is_vf = NULL;
    int status = 0;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *p = line;
        while (isspace((unsigned char)*p)) {
            p++;
        }
        if (*p == '\0' || *p == '#') {
            continue;
        }
        bool vf;
        if (strncmp(p, "vf", 2) == 0 && isspace((unsigned char)p[2])) {
            vf = true;
        } else if (strncmp(p, "ee", 2) == 0 && isspace((unsigned char)p[2])) {
            vf = false;
        } else {
            fprintf(stderr, "weft ccd: %s:%lu: a query starts with 'vf' or 'ee'\n", path, lineno);
            status = 1;
            break;
        }
        if (count == cap) {
            size_t ncap = cap ? 2 * cap : 1024;
            double *nq = realloc(q, ncap * 24 * sizeof *q);
            unsigned char *nv = realloc(is_vf, ncap);
            if (nq) {
                q = nq;
            }
            if (nv) {
                is_vf = nv;
            }
            if (!nq || !nv) {
                fprintf(stderr, "weft ccd: out of memory after %zu queries\n", count);
                status = 1;
                break;
            }
            cap = ncap;
        }
        p += 2;
        double *dst = q + 24 * count;
        int n = 0;
        for (; n < 24; ++n) {
            char *end = NULL;
            dst[n] = strtod(p, &end);
            if (end == p) {
                break;
            }
            p = end;
        }
        while (isspace((unsigned char)*p)) {
            p++;
        }
        if (n != 24 || *p != '\0') {
            fprintf(stderr, "weft ccd: %s:%lu: expected exactly 24 numbers after '%s'\n", path, lineno,
                    vf ? "vf" : "ee");
            status = 1;
            break;
        }
        is_vf[count++] = vf;
    }
    if (f != stdin) {
        fclose(f);
    }
    double *toi = malloc((count ? count : 1) * sizeof *toi);
    unsigned char *hit = malloc(count ? count : 1);
    if (!toi || !hit) {
        fprintf(stderr, "weft ccd: out of memory\n");
        status = 1;
        count = 0;
    }
    size_t hits = 0, vf_count = 0;
    double t0 = weft__now_ms();
    for (size_t i = 0; i < count; ++i) {
        hit[i] = (unsigned char)(is_vf[i] ? weft_ccd_vertex_face(q + 24 * i, eta, &toi[i])
                                          : weft_ccd_edge_edge(q + 24 * i, eta, &toi[i]));
    }
    double ms = weft__now_ms() - t0;
    for (size_t i = 0; i < count; ++i) {
        hits += hit[i];
        vf_count += is_vf[i];
        if (hit[i]) {
            printf("1 %.17g\n", toi[i]);
        } else {
            printf("0\n");
        }
    }
    fprintf(stderr, "weft ccd: %zu queries (%zu vf, %zu ee), %zu collisions, %.3f ms narrow phase, %.4f us per query\n",
            count, vf_count, count - vf_count, hits, ms, count ? 1e3 * ms / (double)count : 0.0);
    free(q);
    free(is_vf);
    free(toi);
    free(hit);
    return status;
}
