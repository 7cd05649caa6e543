/* The measured LOD table: CSV parsing with full validation, and the level pick.
 * The CSV format is documented in include/weft/lod.h; `weft bench lod` writes it. */
#include "lod/lod_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define LOD_MAX_FILE_BYTES (4u << 20) /* a table of 256 levels is ~30 KB; anything huge is not one */
#define LOD_CELL_CAP 128u

enum lod_column {
    COL_LEVEL,
    COL_METHOD,
    COL_MODEL,
    COL_PRECISION,
    COL_SUBSTEPS,
    COL_CCD,
    COL_RESOLUTION,
    COL_MS,
    COL_MVE,
    COL_STRAIN,
    COL_SEQUENCES,
    COL_FRAMES,
    COL_REQUIRED, /* the columns after this one are optional */
    COL_CROP_CM = COL_REQUIRED,
    COL_CROP_RULE,
    COL_CROP_TOKENS,
    COL_TETHER_CM,
    COL_STRAIN_PCT,
    COL_STRAIN_CONTACT_CM,
    COL_PUSH_CM,
    COL_COUNT
};

static const char *const column_names[COL_COUNT] = {
    "level",     "method",    "model",  "precision", "substeps",      "ccd",
    "resolution", "ms_per_frame", "mve_cm", "max_edge_strain", "sequences", "frames",
    "crop_cm",   "collider_crop", "max_collider_tokens", "tether_cm", "strain_limit_pct",
    "strain_contact_cm", "push_cm"};

/* What an absent optional column means: the model's own crop. */
static const char *const column_defaults[COL_COUNT] = {[COL_CROP_CM] = "-",     [COL_CROP_RULE] = "-",
                                                       [COL_CROP_TOKENS] = "-", [COL_TETHER_CM] = "-",
                                                       [COL_STRAIN_PCT] = "-", [COL_STRAIN_CONTACT_CM] = "-",
                                                       [COL_PUSH_CM] = "-"};

/* One line split at commas into trimmed cells (no quoting: no field needs a comma). */
typedef struct lod_line {
    char cells[COL_COUNT + 1][LOD_CELL_CAP];
    uint32_t count;
} lod_line;

static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r'; }

/* Splits [s, e) into cells. False when a cell is too long or there are too many cells. */
static bool split_line(const char *s, const char *e, lod_line *out, uint32_t line_no, weft_result *r)
{
    out->count = 0;
    const char *p = s;
    for (;;) {
        const char *c = p;
        while (c < e && *c != ',') {
            c++;
        }
        const char *a = p, *b = c;
        while (a < b && is_space(*a)) {
            a++;
        }
        while (b > a && is_space(b[-1])) {
            b--;
        }
        if (out->count == COL_COUNT + 1) {
            *r = weft__fail(WEFT_ERROR_FORMAT, "lod table line %u: more than %u columns", line_no, COL_COUNT);
            return false;
        }
        size_t n = (size_t)(b - a);
        if (n >= LOD_CELL_CAP) {
            *r = weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column %u: cell longer than %u characters", line_no,
                            out->count + 1, LOD_CELL_CAP - 1);
            return false;
        }
        for (size_t i = 0; i < n; ++i) {
            if (a[i] == '\0') {
                *r = weft__fail(WEFT_ERROR_FORMAT, "lod table line %u: NUL byte", line_no);
                return false;
            }
        }
        memcpy(out->cells[out->count], a, n);
        out->cells[out->count][n] = '\0';
        out->count++;
        if (c == e) {
            return true;
        }
        p = c + 1;
    }
}

static bool parse_f64(const char *s, double *out)
{
    if (!*s) {
        return false;
    }
    char *end = NULL;
    errno = 0;
    double v = strtod(s, &end);
    if (errno == ERANGE || !end || *end || !isfinite(v)) {
        return false;
    }
    *out = v;
    return true;
}

static bool parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out)
{
    if (!*s || *s == '-' || *s == '+') {
        return false;
    }
    for (const char *p = s; *p; ++p) {
        if (*p < '0' || *p > '9') {
            return false;
        }
    }
    errno = 0;
    unsigned long long v = strtoull(s, NULL, 10);
    if (errno == ERANGE || v < lo || v > hi) {
        return false;
    }
    *out = (uint32_t)v;
    return true;
}

static bool valid_name(const char *s)
{
    size_t n = strlen(s);
    if (n == 0 || n >= WEFT_LOD_NAME_CAP) {
        return false;
    }
    for (size_t i = 0; i < n; ++i) {
        char c = s[i];
        bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '.' ||
                  c == ':' || c == '+' || c == '-';
        if (!ok) {
            return false;
        }
    }
    return true;
}

/* Fills one level from its cells (in canonical column order). */
static weft_result parse_level(char cells[COL_COUNT][LOD_CELL_CAP], uint32_t ln, weft_lod_level *lv)
{
    memset(lv, 0, sizeof *lv);
    const char *c;
    c = cells[COL_LEVEL];
    if (!valid_name(c)) {
        return weft__fail(WEFT_ERROR_FORMAT,
                          "lod table line %u column 'level': '%s' is not a name of 1..%u characters [A-Za-z0-9_.:+-]",
                          ln, c, WEFT_LOD_NAME_CAP - 1);
    }
    memcpy(lv->name, c, strlen(c) + 1);

    c = cells[COL_METHOD];
    if (strcmp(c, "model") == 0) {
        lv->method = WEFT_METHOD_MODEL;
    } else if (strcmp(c, "xpbd") == 0) {
        lv->method = WEFT_METHOD_XPBD;
    } else if (strcmp(c, "lbs") == 0) {
        lv->method = WEFT_METHOD_LBS;
    } else {
        return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column 'method': '%s' is not model, xpbd or lbs", ln, c);
    }
    const bool is_model = lv->method == WEFT_METHOD_MODEL, is_xpbd = lv->method == WEFT_METHOD_XPBD;

    c = cells[COL_MODEL];
    if (is_model) {
        if (strcmp(c, "-") == 0 || !valid_name(c)) {
            return weft__fail(WEFT_ERROR_FORMAT,
                              "lod table line %u column 'model': method model needs a model name, got '%s'", ln, c);
        }
        memcpy(lv->model, c, strlen(c) + 1);
    } else if (strcmp(c, "-") != 0) {
        return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column 'model': '-' expected for method %s, got '%s'",
                          ln, cells[COL_METHOD], c);
    }

    c = cells[COL_PRECISION];
    lv->precision = WEFT_PRECISION_FP32;
    if (is_model) {
        if (strcmp(c, "fp32") == 0) {
            lv->precision = WEFT_PRECISION_FP32;
        } else if (strcmp(c, "fp16") == 0) {
            lv->precision = WEFT_PRECISION_FP16;
        } else if (strcmp(c, "int8") == 0) {
            lv->precision = WEFT_PRECISION_INT8;
        } else {
            return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column 'precision': '%s' is not fp32, fp16 or int8",
                              ln, c);
        }
    } else if (strcmp(c, "-") != 0) {
        return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column 'precision': '-' expected for method %s, got '%s'",
                          ln, cells[COL_METHOD], c);
    }

    c = cells[COL_SUBSTEPS];
    if (is_xpbd) {
        if (!parse_u32(c, 1, 1000, &lv->substeps)) {
            return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column 'substeps': '%s' is not an integer in 1..1000",
                              ln, c);
        }
    } else if (strcmp(c, "-") != 0) {
        return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column 'substeps': '-' expected for method %s, got '%s'",
                          ln, cells[COL_METHOD], c);
    }

    c = cells[COL_CCD];
    if (strcmp(c, "on") == 0) {
        lv->ccd = true;
    } else if (strcmp(c, "off") != 0) {
        return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column 'ccd': '%s' is not on or off", ln, c);
    }

    c = cells[COL_RESOLUTION];
    if (!parse_f64(c, &lv->resolution) || !(lv->resolution > 0.0 && lv->resolution <= 1.0)) {
        return weft__fail(WEFT_ERROR_FORMAT,
                          "lod table line %u column 'resolution': '%s' is not in (0, 1] (the simulated mesh's share of "
                          "the drawn mesh's vertices; 1: the drawn mesh itself)", ln, c);
    }

    static const struct {
        int col;
        double lo;
        bool open_lo;
    } nums[] = {{COL_MS, 0.0, true}, {COL_MVE, 0.0, false}, {COL_STRAIN, 0.0, false}};
    double *dst[] = {&lv->ms_per_frame, &lv->mve_cm, &lv->max_edge_strain};
    for (size_t i = 0; i < sizeof nums / sizeof nums[0]; ++i) {
        c = cells[nums[i].col];
        double v = 0;
        if (!parse_f64(c, &v) || (nums[i].open_lo ? !(v > nums[i].lo) : !(v >= nums[i].lo))) {
            return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column '%s': '%s' is not a finite number %s 0", ln,
                              column_names[nums[i].col], c, nums[i].open_lo ? ">" : ">=");
        }
        *dst[i] = v;
    }
    if (!parse_u32(cells[COL_SEQUENCES], 1, UINT32_MAX, &lv->sequences)) {
        return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column 'sequences': '%s' is not an integer >= 1", ln,
                          cells[COL_SEQUENCES]);
    }
    if (!parse_u32(cells[COL_FRAMES], 1, UINT32_MAX, &lv->frames)) {
        return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column 'frames': '%s' is not an integer >= 1", ln,
                          cells[COL_FRAMES]);
    }

    /* Collider crop: model levels only; '-' is the model's own. */
    for (int k = COL_CROP_CM; k <= COL_CROP_TOKENS; ++k) {
        if (!is_model && strcmp(cells[k], "-") != 0) {
            return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column '%s': '-' expected for method %s, got '%s'",
                              ln, column_names[k], cells[COL_METHOD], cells[k]);
        }
    }
    c = cells[COL_CROP_CM];
    if (strcmp(c, "-") != 0 && (!parse_f64(c, &lv->crop_cm) || !(lv->crop_cm > 0.0) || lv->crop_cm > 10000.0)) {
        return weft__fail(WEFT_ERROR_FORMAT,
                          "lod table line %u column 'crop_cm': '%s' is not '-' (the model's own) or a number in (0, 10000]",
                          ln, c);
    }
    c = cells[COL_CROP_RULE];
    lv->collider_crop = WEFT_COLLIDER_CROP_BOX;
    if (strcmp(c, "cells") == 0) {
        lv->collider_crop = WEFT_COLLIDER_CROP_CELLS;
    } else if (strcmp(c, "-") != 0 && strcmp(c, "box") != 0) {
        return weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column 'collider_crop': '%s' is not -, box or cells",
                          ln, c);
    }
    c = cells[COL_CROP_TOKENS];
    if (strcmp(c, "-") != 0 && !parse_u32(c, 1, UINT32_MAX, &lv->max_collider_tokens)) {
        return weft__fail(WEFT_ERROR_FORMAT,
                          "lod table line %u column 'max_collider_tokens': '%s' is not '-' (no cap) or an integer >= 1",
                          ln, c);
    }
    /* Tethers and strain limit (every method; weft_garment_def.tethers.distance / strain_limit). */
    c = cells[COL_TETHER_CM];
    if (strcmp(c, "-") != 0 && (!parse_f64(c, &lv->tether_cm) || !(lv->tether_cm > 0.0) || lv->tether_cm > 1e5)) {
        return weft__fail(WEFT_ERROR_FORMAT,
                          "lod table line %u column 'tether_cm': '%s' is not '-' (no tethers) or a number in (0, 100000]",
                          ln, c);
    }
    c = cells[COL_STRAIN_PCT];
    if (strcmp(c, "-") != 0 &&
        (!parse_f64(c, &lv->strain_limit_pct) || !(lv->strain_limit_pct > 0.0) || lv->strain_limit_pct > 1000.0)) {
        return weft__fail(WEFT_ERROR_FORMAT,
                          "lod table line %u column 'strain_limit_pct': '%s' is not '-' (no limit) or a number in "
                          "(0, 1000]", ln, c);
    }
    c = cells[COL_STRAIN_CONTACT_CM];
    if (strcmp(c, "-") != 0 && (lv->strain_limit_pct == 0.0 || !parse_f64(c, &lv->strain_contact_cm) ||
                                !(lv->strain_contact_cm > 0.0) || lv->strain_contact_cm > 100.0)) {
        return weft__fail(WEFT_ERROR_FORMAT,
                          "lod table line %u column 'strain_contact_cm': '%s' is not '-' (plain limit) or, with a "
                          "strain limit, a number in (0, 100]", ln, c);
    }
    c = cells[COL_PUSH_CM];
    if (strcmp(c, "-") != 0 && (!parse_f64(c, &lv->push_cm) || !(lv->push_cm > 0.0) || lv->push_cm > 10.0)) {
        return weft__fail(WEFT_ERROR_FORMAT,
                          "lod table line %u column 'push_cm': '%s' is not '-' (no push) or a number in (0, 10]", ln, c);
    }
    return WEFT_OK;
}

weft_result weft_lod_table_load_memory(weft_context *ctx, const char *text, size_t size, weft_lod_table **out)
{
    if (!ctx || !out || (!text && size > 0)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_table_load_memory: context, text and out are required");
    }
    if (size > LOD_MAX_FILE_BYTES) {
        return weft__fail(WEFT_ERROR_FORMAT, "lod table: %zu bytes is over the %u-byte cap", size, LOD_MAX_FILE_BYTES);
    }
    /* Parse into a stack-free scratch first; the table is allocated once the count is known. */
    weft_lod_level *levels = weft__alloc(ctx, WEFT_LOD_MAX_LEVELS * sizeof *levels);
    lod_line *line = weft__alloc(ctx, sizeof *line);
    if (!levels || !line) {
        weft__free(ctx, levels, WEFT_LOD_MAX_LEVELS * sizeof *levels);
        weft__free(ctx, line, sizeof *line);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    int map[COL_COUNT]; /* canonical column -> position in the file */
    bool have_header = false;
    uint32_t count = 0, line_no = 0, header_count = 0;
    weft_result r = WEFT_OK;
    const char *p = text, *end = text + size;
    char cells[COL_COUNT][LOD_CELL_CAP];
    while (r == WEFT_OK && p < end) {
        const char *e = p;
        while (e < end && *e != '\n') {
            e++;
        }
        line_no++;
        const char *a = p;
        while (a < e && is_space(*a)) {
            a++;
        }
        const char *next = e < end ? e + 1 : e;
        if (a == e || *a == '#') {
            p = next;
            continue;
        }
        if (!split_line(a, e, line, line_no, &r)) {
            break;
        }
        if (!have_header) {
            for (int k = 0; k < COL_COUNT; ++k) {
                map[k] = -1;
            }
            if (line->count < COL_REQUIRED || line->count > COL_COUNT) {
                r = weft__fail(WEFT_ERROR_FORMAT,
                               "lod table line %u: header has %u columns, expected %u to %u (%s, ...)", line_no,
                               line->count, COL_REQUIRED, COL_COUNT, column_names[0]);
                break;
            }
            for (uint32_t i = 0; i < line->count && r == WEFT_OK; ++i) {
                int k = 0;
                while (k < COL_COUNT && strcmp(line->cells[i], column_names[k]) != 0) {
                    k++;
                }
                if (k == COL_COUNT) {
                    r = weft__fail(WEFT_ERROR_FORMAT, "lod table line %u: unknown column '%s'", line_no, line->cells[i]);
                } else if (map[k] >= 0) {
                    r = weft__fail(WEFT_ERROR_FORMAT, "lod table line %u: column '%s' appears twice", line_no,
                                   line->cells[i]);
                } else {
                    map[k] = (int)i;
                }
            }
            for (int k = 0; k < COL_REQUIRED && r == WEFT_OK; ++k) {
                if (map[k] < 0) {
                    r = weft__fail(WEFT_ERROR_FORMAT, "lod table line %u: header lacks the column '%s'", line_no,
                                   column_names[k]);
                }
            }
            header_count = line->count;
            have_header = true;
            p = next;
            continue;
        }
        if (line->count != header_count) {
            r = weft__fail(WEFT_ERROR_FORMAT, "lod table line %u: %u columns, the header has %u", line_no, line->count,
                           header_count);
            break;
        }
        if (count == WEFT_LOD_MAX_LEVELS) {
            r = weft__fail(WEFT_ERROR_FORMAT, "lod table line %u: more than %u levels", line_no, WEFT_LOD_MAX_LEVELS);
            break;
        }
        for (int k = 0; k < COL_COUNT; ++k) {
            if (map[k] >= 0) {
                memcpy(cells[k], line->cells[map[k]], LOD_CELL_CAP);
            } else {
                snprintf(cells[k], LOD_CELL_CAP, "%s", column_defaults[k]);
            }
        }
        r = parse_level(cells, line_no, &levels[count]);
        for (uint32_t j = 0; r == WEFT_OK && j < count; ++j) {
            if (strcmp(levels[j].name, levels[count].name) == 0) {
                r = weft__fail(WEFT_ERROR_FORMAT, "lod table line %u column 'level': '%s' is defined twice", line_no,
                               levels[count].name);
            }
        }
        count += r == WEFT_OK;
        p = next;
    }
    if (r == WEFT_OK && !have_header) {
        r = weft__fail(WEFT_ERROR_FORMAT, "lod table: no header line (%s,%s,...)", column_names[0], column_names[1]);
    }
    if (r == WEFT_OK && count == 0) {
        r = weft__fail(WEFT_ERROR_FORMAT, "lod table: no levels after the header");
    }
    weft_lod_table *t = NULL;
    if (r == WEFT_OK) {
        t = weft__alloc(ctx, sizeof *t);
        weft_lod_level *lv = t ? weft__alloc(ctx, count * sizeof *lv) : NULL;
        if (!lv) {
            weft__free(ctx, t, sizeof *t);
            r = WEFT_ERROR_OUT_OF_MEMORY;
        } else {
            memcpy(lv, levels, count * sizeof *lv);
            t->ctx = ctx;
            t->levels = lv;
            t->count = count;
        }
    }
    weft__free(ctx, levels, WEFT_LOD_MAX_LEVELS * sizeof *levels);
    weft__free(ctx, line, sizeof *line);
    if (r == WEFT_OK) {
        *out = t;
    }
    return r;
}

weft_result weft_lod_table_load_file(weft_context *ctx, const char *path, weft_lod_table **out)
{
    if (!ctx || !path || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_table_load_file: context, path and out are required");
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "lod table '%s': cannot open: %s", path, strerror(errno));
    }
    char *buf = weft__alloc(ctx, LOD_MAX_FILE_BYTES + 1);
    if (!buf) {
        fclose(f);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    size_t n = fread(buf, 1, LOD_MAX_FILE_BYTES + 1, f);
    bool err = ferror(f) != 0;
    fclose(f);
    weft_result r;
    if (err) {
        r = weft__fail(WEFT_ERROR_IO, "lod table '%s': read error", path);
    } else if (n > LOD_MAX_FILE_BYTES) {
        r = weft__fail(WEFT_ERROR_FORMAT, "lod table '%s': larger than %u bytes", path, LOD_MAX_FILE_BYTES);
    } else {
        r = weft_lod_table_load_memory(ctx, buf, n, out);
    }
    weft__free(ctx, buf, LOD_MAX_FILE_BYTES + 1);
    return r;
}

void weft_lod_table_destroy(weft_lod_table *t)
{
    if (!t) {
        return;
    }
    const weft_context *ctx = t->ctx;
    weft__free(ctx, t->levels, t->count * sizeof *t->levels);
    weft__free(ctx, t, sizeof *t);
}

uint32_t weft_lod_table_count(const weft_lod_table *t) { return t ? t->count : 0; }

const weft_lod_level *weft_lod_table_level(const weft_lod_table *t, uint32_t i)
{
    return t && i < t->count ? &t->levels[i] : NULL;
}

weft_result weft_lod_table_find(const weft_lod_table *t, const char *name, uint32_t *out_index)
{
    if (!t || !name || !out_index) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_table_find: table, name and out_index are required");
    }
    for (uint32_t i = 0; i < t->count; ++i) {
        if (strcmp(t->levels[i].name, name) == 0) {
            *out_index = i;
            return WEFT_OK;
        }
    }
    return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_table_find: no level named '%s'", name);
}

/* ---------------------------------------------------------------------------------------- */

/* a is a better "cheap" choice than b: lower cost, then lower error, then earlier. */
static bool cheaper(const weft_lod_level *a, const weft_lod_level *b)
{
    if (a->ms_per_frame != b->ms_per_frame) {
        return a->ms_per_frame < b->ms_per_frame;
    }
    return a->mve_cm < b->mve_cm;
}

static bool more_accurate(const weft_lod_level *a, const weft_lod_level *b)
{
    if (a->mve_cm != b->mve_cm) {
        return a->mve_cm < b->mve_cm;
    }
    return a->ms_per_frame < b->ms_per_frame;
}

weft_lod_pick_result weft_lod_pick(const weft_lod_table *t, double budget_ms, double max_mve_cm, uint32_t *out_level)
{
    return weft_lod_pick_among(t, NULL, budget_ms, max_mve_cm, out_level);
}

weft_lod_pick_result weft_lod_pick_among(const weft_lod_table *t, const uint8_t *usable, double budget_ms,
                                         double max_mve_cm, uint32_t *out_level)
{
    if (!t || !out_level || t->count == 0) {
        weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_pick: a loaded table and out_level are required");
        return WEFT_LOD_PICK_INVALID;
    }
    /* NaN fails both comparisons; +inf means "no limit" and is accepted. */
    if (!(budget_ms > 0.0) || !(max_mve_cm > 0.0)) {
        weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_pick: budget_ms (%g) and max_mve_cm (%g) must be positive",
                   budget_ms, max_mve_cm);
        return WEFT_LOD_PICK_INVALID;
    }
    int meets = -1, in_budget = -1, cheapest = -1;
    for (uint32_t i = 0; i < t->count; ++i) {
        const weft_lod_level *l = &t->levels[i];
        if (usable && !usable[i]) {
            continue;
        }
        if (cheapest < 0 || cheaper(l, &t->levels[cheapest])) {
            cheapest = (int)i;
        }
        if (l->ms_per_frame > budget_ms) {
            continue;
        }
        if (in_budget < 0 || more_accurate(l, &t->levels[in_budget])) {
            in_budget = (int)i;
        }
        if (l->mve_cm <= max_mve_cm && (meets < 0 || cheaper(l, &t->levels[meets]))) {
            meets = (int)i;
        }
    }
    if (cheapest < 0) {
        weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_pick_among: no level of the %u is marked usable", t->count);
        return WEFT_LOD_PICK_INVALID;
    }
    if (meets >= 0) {
        *out_level = (uint32_t)meets;
        return WEFT_LOD_PICK_OK;
    }
    if (in_budget >= 0) {
        *out_level = (uint32_t)in_budget;
        return WEFT_LOD_PICK_ACCURACY_MISSED;
    }
    *out_level = (uint32_t)cheapest;
    return WEFT_LOD_PICK_OVER_BUDGET;
}

const char *weft_lod_pick_result_string(weft_lod_pick_result r)
{
    switch (r) {
    case WEFT_LOD_PICK_OK:
        return "meets budget and accuracy";
    case WEFT_LOD_PICK_ACCURACY_MISSED:
        return "accuracy target missed: most accurate level within budget";
    case WEFT_LOD_PICK_OVER_BUDGET:
        return "over budget: cheapest level";
    case WEFT_LOD_PICK_INVALID:
        return "invalid arguments";
    }
    return "unknown";
}
