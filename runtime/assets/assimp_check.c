/* Checks a skinned-mesh file for inputs assimp 5.2 crashes on (assimp_check.h). The FBX walkers
 * follow assimp's own tokenizers (FBXTokenizer.cpp, FBXBinaryTokenizer.cpp) closely enough to
 * see every connection and every nesting level assimp will see; where assimp's tokenizer would
 * throw, the walk stops and the file is left to assimp, which then refuses it. */
#define _POSIX_C_SOURCE 200809L

#include "assimp_check.h"
#include "core/core.h"

#include <cjson/cJSON.h>
#include <zlib.h>

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CHECK_MAX_FILE_BYTES ((uint64_t)2 << 30) /* larger glTF / FBX files are refused */
#define CHECK_MAX_DEPTH 64u                      /* FBX scopes nested deeper are refused */
#define CHECK_MAX_CONNECTIONS (1u << 24)

/* ---------------------------------------------------------------------------------------- */
/* glTF                                                                                       */

/* Whether item is a whole number in [0, count): an index into an array of `count`. */
static bool gltf_index(const cJSON *item, int count)
{
    return cJSON_IsNumber(item) && item->valuedouble >= 0 && item->valuedouble < count &&
           item->valuedouble == floor(item->valuedouble);
}

/* The references assimp 5.2 follows without checking: every mesh primitive has an `attributes`
 * object with POSITION, each attribute and `indices` an accessor that exists (a primitive without
 * attributes made its glTF reader read address 0); every animation channel names a sampler and a
 * node that exist, every sampler input and output accessor exists. Returns NULL, or what is
 * wrong. */
static const char *gltf_references(const cJSON *doc, char *why, size_t size)
{
    const int accessors = cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(doc, "accessors"));
    const int nodes = cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(doc, "nodes"));
    const cJSON *mesh, *prim, *attr;
    int m = 0;
    cJSON_ArrayForEach(mesh, cJSON_GetObjectItemCaseSensitive(doc, "meshes"))
    {
        int k = 0;
        cJSON_ArrayForEach(prim, cJSON_GetObjectItemCaseSensitive(mesh, "primitives"))
        {
            const cJSON *attrs = cJSON_GetObjectItemCaseSensitive(prim, "attributes");
            const cJSON *indices = cJSON_GetObjectItemCaseSensitive(prim, "indices");
            if (!cJSON_IsObject(attrs) || !gltf_index(cJSON_GetObjectItemCaseSensitive(attrs, "POSITION"), accessors)) {
                snprintf(why, size, "mesh %d primitive %d has no attributes with a POSITION accessor", m, k);
                return why;
            }
            cJSON_ArrayForEach(attr, attrs)
            {
                if (!gltf_index(attr, accessors)) {
                    snprintf(why, size, "mesh %d primitive %d: attribute %.32s names no accessor", m, k,
                             attr->string ? attr->string : "?");
                    return why;
                }
            }
            if (indices && !gltf_index(indices, accessors)) {
                snprintf(why, size, "mesh %d primitive %d: indices name no accessor", m, k);
                return why;
            }
            ++k;
        }
        ++m;
    }
    const cJSON *anim, *item;
    int a = 0;
    cJSON_ArrayForEach(anim, cJSON_GetObjectItemCaseSensitive(doc, "animations"))
    {
        const int samplers = cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(anim, "samplers"));
        cJSON_ArrayForEach(item, cJSON_GetObjectItemCaseSensitive(anim, "samplers"))
        {
            if (!gltf_index(cJSON_GetObjectItemCaseSensitive(item, "input"), accessors) ||
                !gltf_index(cJSON_GetObjectItemCaseSensitive(item, "output"), accessors)) {
                snprintf(why, size, "animation %d: a sampler's input or output names no accessor", a);
                return why;
            }
        }
        cJSON_ArrayForEach(item, cJSON_GetObjectItemCaseSensitive(anim, "channels"))
        {
            const cJSON *target = cJSON_GetObjectItemCaseSensitive(item, "target");
            if (!gltf_index(cJSON_GetObjectItemCaseSensitive(item, "sampler"), samplers) ||
                !gltf_index(cJSON_GetObjectItemCaseSensitive(target, "node"), nodes)) {
                snprintf(why, size, "animation %d: a channel names no sampler or no target node", a);
                return why;
            }
        }
        ++a;
    }
    return NULL;
}

/* The references above, and every skin must name inverseBindMatrices: a float MAT4 accessor with
 * a matrix per joint. */
static weft_result check_gltf_json(const char *path, const char *text, size_t len)
{
    cJSON *doc = cJSON_ParseWithLength(text, len);
    if (!doc) {
        return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: '%s' is not valid glTF JSON", path);
    }
    weft_result res = WEFT_OK;
    char why[160];
    if (gltf_references(doc, why, sizeof why)) {
        res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: '%s': %s (assimp 5.2 reads address 0 on such files)", path,
                         why);
    }
    const cJSON *skins = cJSON_GetObjectItemCaseSensitive(doc, "skins");
    const cJSON *accessors = cJSON_GetObjectItemCaseSensitive(doc, "accessors");
    const int accessor_count = cJSON_IsArray(accessors) ? cJSON_GetArraySize(accessors) : 0;
    const int skin_count = cJSON_IsArray(skins) ? cJSON_GetArraySize(skins) : 0;
    for (int i = 0; i < skin_count && res == WEFT_OK; ++i) {
        const cJSON *skin = cJSON_GetArrayItem(skins, i);
        const cJSON *joints = cJSON_GetObjectItemCaseSensitive(skin, "joints");
        const cJSON *ibm = cJSON_GetObjectItemCaseSensitive(skin, "inverseBindMatrices");
        const double joint_count = cJSON_IsArray(joints) ? (double)cJSON_GetArraySize(joints) : 0.0;
        const cJSON *acc = NULL;
        if (cJSON_IsNumber(ibm) && ibm->valuedouble >= 0 && ibm->valuedouble < accessor_count &&
            ibm->valuedouble == floor(ibm->valuedouble)) {
            acc = cJSON_GetArrayItem(accessors, (int)ibm->valuedouble);
        }
        const cJSON *type = cJSON_GetObjectItemCaseSensitive(acc, "type");
        const cJSON *component = cJSON_GetObjectItemCaseSensitive(acc, "componentType");
        const cJSON *count = cJSON_GetObjectItemCaseSensitive(acc, "count");
        if (!acc || !cJSON_IsString(type) || strcmp(type->valuestring, "MAT4") != 0 || !cJSON_IsNumber(component) ||
            component->valuedouble != 5126 || !cJSON_IsNumber(count) || !(count->valuedouble >= joint_count)) {
            res = weft__fail(WEFT_ERROR_FORMAT,
                             "skinned mesh: '%s': skin %d needs inverseBindMatrices, a float MAT4 accessor with one "
                             "matrix per joint (assimp 5.2 crashes on other skins)",
                             path, i);
        }
    }
    cJSON_Delete(doc);
    return res;
}

/* The JSON of a .glb (its first chunk) or of a text glTF (first non-blank byte '{'); NULL when
 * the file is neither. *bad names what is wrong with a file that starts like a .glb but is not
 * the glTF 2.0 binary layout (version 2, declared length = file size, a JSON chunk that fits):
 * assimp reads such headers anyway, and one of them (version 670722, 55 bytes) kept it busy for
 * minutes. */
static const char *gltf_json(const uint8_t *data, size_t size, size_t *len, const char **bad)
{
    *bad = NULL;
    if (size >= 4 && memcmp(data, "glTF", 4) == 0) {
        if (size < 20) {
            *bad = "a glb header needs 20 bytes";
            return NULL;
        }
        const uint32_t version = (uint32_t)data[4] | (uint32_t)data[5] << 8 | (uint32_t)data[6] << 16 |
                                 (uint32_t)data[7] << 24;
        const uint32_t length = (uint32_t)data[8] | (uint32_t)data[9] << 8 | (uint32_t)data[10] << 16 |
                                (uint32_t)data[11] << 24;
        const uint32_t chunk = (uint32_t)data[12] | (uint32_t)data[13] << 8 | (uint32_t)data[14] << 16 |
                               (uint32_t)data[15] << 24;
        if (version != 2) {
            *bad = "only glTF 2.0 binary (glb version 2) is read";
        } else if (length != size) {
            *bad = "the glb header's length is not the file's size";
        } else if (memcmp(data + 16, "JSON", 4) != 0) {
            *bad = "the glb has no JSON chunk first";
        } else if (chunk > size - 20) {
            *bad = "the glb JSON chunk runs past the end of the file";
        }
        if (*bad) {
            return NULL;
        }
        *len = chunk;
        return (const char *)data + 20;
    }
    size_t i = 0;
    while (i < size && (data[i] == ' ' || data[i] == '\t' || data[i] == '\n' || data[i] == '\r')) {
        i++;
    }
    if (i == size || data[i] != '{') {
        return NULL;
    }
    *len = size;
    return (const char *)data;
}

/* ---------------------------------------------------------------------------------------- */
/* FBX connections                                                                            */

typedef struct links {
    uint64_t (*edge)[3]; /* source, destination, 1 for an object-object ("OO") connection */
    size_t count, cap;
    bool too_many, out_of_memory;
} links;

static bool links_add(links *l, uint64_t src, uint64_t dst, bool oo)
{
    if (l->count == l->cap) {
        if (l->cap >= CHECK_MAX_CONNECTIONS) {
            l->too_many = true;
            return false;
        }
        size_t cap = l->cap ? 2 * l->cap : 256;
        void *grown = realloc(l->edge, cap * sizeof *l->edge);
        if (!grown) {
            l->out_of_memory = true;
            return false;
        }
        l->edge = grown;
        l->cap = cap;
    }
    l->edge[l->count][0] = src;
    l->edge[l->count][1] = dst;
    l->edge[l->count][2] = oo;
    l->count++;
    return true;
}

static int cmp_pair(const void *a, const void *b)
{
    const uint64_t *x = a, *y = b;
    return x[0] != y[0] ? (x[0] < y[0] ? -1 : 1) : (x[1] < y[1] ? -1 : x[1] > y[1]);
}

/* 1 when an object-object connection is listed twice (assimp 5.2 then adds a skin cluster to its
 * skin twice and frees it twice; it takes every type but "OP" and "PP" as object to object), 0
 * when none is, -1 out of memory. Object-property connections repeat legitimately (one per
 * property). */
static int links_duplicate(const links *l)
{
    uint64_t (*pairs)[2] = malloc((l->count ? l->count : 1) * sizeof *pairs);
    if (!pairs) {
        return -1;
    }
    size_t n = 0;
    for (size_t i = 0; i < l->count; ++i) {
        if (l->edge[i][2]) {
            pairs[n][0] = l->edge[i][0];
            pairs[n][1] = l->edge[i][1];
            n++;
        }
    }
    qsort(pairs, n, sizeof *pairs, cmp_pair);
    int dup = 0;
    for (size_t i = 1; i < n && !dup; ++i) {
        dup = pairs[i][0] == pairs[i - 1][0] && pairs[i][1] == pairs[i - 1][1];
    }
    free(pairs);
    return dup;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static uint32_t id_index(const uint64_t *ids, size_t n, uint64_t id)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (ids[mid] < id) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    return (uint32_t)lo;
}

/* 1 when the connections contain a cycle (a self-connection included), 0 when not, -1 when out
 * of memory. Kahn's algorithm: repeatedly drop objects nothing points at any more. */
static int links_cycle(const links *l)
{
    const size_t m = l->count;
    if (m == 0) {
        return 0;
    }
    uint64_t *ids = malloc(2 * m * sizeof *ids);
    if (!ids) {
        return -1;
    }
    for (size_t i = 0; i < m; ++i) {
        ids[2 * i] = l->edge[i][0];
        ids[2 * i + 1] = l->edge[i][1];
    }
    qsort(ids, 2 * m, sizeof *ids, cmp_u64);
    size_t n = 0;
    for (size_t i = 0; i < 2 * m; ++i) {
        if (n == 0 || ids[n - 1] != ids[i]) {
            ids[n++] = ids[i];
        }
    }
    uint32_t *first = calloc(n + 1, sizeof *first), *fill = malloc((n + 1) * sizeof *fill);
    uint32_t *next = malloc(m * sizeof *next), *indegree = calloc(n, sizeof *indegree), *queue = malloc(n * sizeof *queue);
    int cycle = -1;
    if (first && fill && next && indegree && queue) {
        for (size_t i = 0; i < m; ++i) {
            first[id_index(ids, n, l->edge[i][0]) + 1]++;
            indegree[id_index(ids, n, l->edge[i][1])]++;
        }
        for (size_t v = 0; v < n; ++v) {
            first[v + 1] += first[v];
        }
        memcpy(fill, first, (n + 1) * sizeof *fill);
        for (size_t i = 0; i < m; ++i) {
            next[fill[id_index(ids, n, l->edge[i][0])]++] = id_index(ids, n, l->edge[i][1]);
        }
        size_t head = 0, tail = 0;
        for (size_t v = 0; v < n; ++v) {
            if (indegree[v] == 0) {
                queue[tail++] = (uint32_t)v;
            }
        }
        while (head < tail) {
            const uint32_t v = queue[head++];
            for (uint32_t e = first[v]; e < first[v + 1]; ++e) {
                if (--indegree[next[e]] == 0) {
                    queue[tail++] = next[e];
                }
            }
        }
        cycle = tail < n;
    }
    free(ids);
    free(first);
    free(fill);
    free(next);
    free(indegree);
    free(queue);
    return cycle;
}

/* ---------------------------------------------------------------------------------------- */
/* FBX, ASCII: assimp's tokenizer reads up to the first NUL; tokens are quoted strings, runs of
 * other bytes, ',' '{' '}', and a run followed by ':' is a key. ';' starts a comment. */

typedef enum { TOK_END, TOK_DATA, TOK_KEY, TOK_COMMA, TOK_OPEN, TOK_CLOSE, TOK_ERROR } tok_type;

typedef struct ascii_lexer {
    const char *p, *end;
    const char *text, *text_end; /* the last DATA / KEY token */
} ascii_lexer;

static bool fbx_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f'; }

static tok_type lex(ascii_lexer *x)
{
    for (;;) {
        if (x->p == x->end) {
            return TOK_END;
        }
        const char c = *x->p;
        if (c == ';') {
            while (x->p < x->end && *x->p != '\r' && *x->p != '\n' && *x->p != '\f') {
                x->p++;
            }
            continue;
        }
        if (fbx_space(c)) {
            x->p++;
            continue;
        }
        x->p++;
        switch (c) {
        case ',':
            return TOK_COMMA;
        case '{':
            return TOK_OPEN;
        case '}':
            return TOK_CLOSE;
        case ':':
            return TOK_ERROR; /* a colon with no key before it */
        case '"':
            x->text = x->p - 1;
            while (x->p < x->end && *x->p != '"') {
                x->p++;
            }
            if (x->p == x->end) {
                return TOK_ERROR; /* unterminated string */
            }
            x->p++;
            x->text_end = x->p;
            return TOK_DATA;
        default:
            break;
        }
        x->text = x->p - 1;
        while (x->p < x->end && !fbx_space(*x->p) && !strchr(",{}:;\"", *x->p)) {
            x->p++;
        }
        x->text_end = x->p;
        if (x->p < x->end && *x->p == '"') {
            return TOK_ERROR; /* a quote inside a token */
        }
        if (x->p < x->end && *x->p == ':') { /* the colon must follow at once: "C :" is an error there */
            x->p++;
            return TOK_KEY;
        }
        return TOK_DATA;
    }
}

/* assimp's strtoul10_64 over a token: false when it would throw (no leading digit); an overflow
 * gives 0, as there. */
static bool ascii_id(const char *s, const char *e, uint64_t *out)
{
    if (s == e || *s < '0' || *s > '9') {
        return false;
    }
    uint64_t v = 0;
    for (; s < e && *s >= '0' && *s <= '9'; ++s) {
        uint64_t nv = v * 10u + (uint64_t)(*s - '0');
        if (nv < v) {
            *out = 0;
            return true;
        }
        v = nv;
    }
    *out = v;
    return true;
}

/* Returns false when the walk had to stop (a token assimp refuses); depth and connections seen
 * so far are in *max_depth and *l. */
static bool walk_fbx_ascii(const char *text, size_t size, uint32_t *max_depth, links *l, bool *empty_key)
{
    const char *nul = memchr(text, '\0', size);
    ascii_lexer x = {text, nul ? nul : text + size, NULL, NULL};
    uint32_t depth = 0;
    tok_type t = lex(&x), last = TOK_END;
    while (t != TOK_END && t != TOK_ERROR) {
        /* a key followed by another key, a '}' or the end has no value: assimp 5.2 frees twice on
         * such an element ("Version: 1000Properties70: {", a line break lost) */
        *empty_key = *empty_key || (last == TOK_KEY && (t == TOK_KEY || t == TOK_CLOSE));
        last = t;
        if (t == TOK_OPEN) {
            depth++;
            *max_depth = depth > *max_depth ? depth : *max_depth;
        } else if (t == TOK_CLOSE) {
            depth -= depth > 0;
        }
        if (t != TOK_KEY || x.text_end - x.text != 1 || x.text[0] != 'C') {
            t = lex(&x);
            continue;
        }
        /* C: "OO", source, destination[, "property"]: the data tokens up to the next key or bracket */
        const char *tok[3][2];
        int n = 0;
        while ((t = lex(&x)) == TOK_DATA || t == TOK_COMMA) {
            if (t == TOK_DATA && n < 3) {
                tok[n][0] = x.text;
                tok[n][1] = x.text_end;
                n++;
            }
            last = t;
        }
        uint64_t src, dst;
        bool pp = n >= 1 && tok[0][1] - tok[0][0] == 4 && memcmp(tok[0][0], "\"PP\"", 4) == 0;
        /* assimp takes every connection but "PP" and "OP" as object to object ("OO", "OOx", ...) */
        bool oo = !(n >= 1 && tok[0][1] - tok[0][0] == 4 && memcmp(tok[0][0], "\"OP\"", 4) == 0);
        if (n == 3 && !pp && ascii_id(tok[1][0], tok[1][1], &src) && ascii_id(tok[2][0], tok[2][1], &dst) &&
            !links_add(l, src, dst, oo)) {
            return false;
        }
    }
    *empty_key = *empty_key || (last == TOK_KEY && t == TOK_END);
    return t == TOK_END;
}

/* ---------------------------------------------------------------------------------------- */
/* FBX, binary: nested records (end offset, property count, property bytes, name, properties,
 * children closed by a NUL record). */

typedef struct fbx_bin {
    const uint8_t *data;
    size_t size;
    bool wide; /* version >= 7500: 64-bit record header fields */
    uint32_t max_depth;
    links *links;
    int64_t control_points; /* the most of any Vertices array (xyz triplets) */
    int64_t max_index;      /* the largest skin cluster index (Indexes arrays); -1: none */
    bool bad_index;         /* a negative index, or an Indexes array that does not decode */
} fbx_bin;

static bool read_uint(const fbx_bin *b, size_t *at, size_t limit, int bytes, uint64_t *out)
{
    if (limit - *at < (size_t)bytes) {
        return false;
    }
    uint64_t v = 0;
    for (int i = bytes - 1; i >= 0; --i) {
        v = v << 8 | b->data[*at + (size_t)i];
    }
    *at += (size_t)bytes;
    *out = v;
    return true;
}

/* The values of an 'i' array property at data[p..] (type code, length, encoding, byte count,
 * payload; skip_property checked its bounds): the largest into b->max_index, a negative value or
 * a payload that does not inflate to length x 4 bytes sets b->bad_index. */
static void scan_index_array(fbx_bin *b, size_t p)
{
    size_t q = p + 1;
    uint64_t len = 0, enc = 0, comp = 0;
    read_uint(b, &q, b->size, 4, &len);
    read_uint(b, &q, b->size, 4, &enc);
    read_uint(b, &q, b->size, 4, &comp);
    if (len > (64u << 20)) { /* 64 M indices: more than any skin weft loads */
        b->bad_index = true;
        return;
    }
    const uint8_t *v = b->data + q;
    uint8_t *inflated = NULL;
    if (enc == 1) {
        uLongf out = (uLongf)(len * 4);
        inflated = malloc(len ? (size_t)len * 4 : 1);
        if (!inflated || uncompress(inflated, &out, v, (uLong)comp) != Z_OK || out != len * 4) {
            free(inflated);
            b->bad_index = true;
            return;
        }
        v = inflated;
    }
    for (uint64_t i = 0; i < len; ++i) {
        const int32_t x = (int32_t)((uint32_t)v[4 * i] | (uint32_t)v[4 * i + 1] << 8 | (uint32_t)v[4 * i + 2] << 16 |
                                    (uint32_t)v[4 * i + 3] << 24);
        b->bad_index = b->bad_index || x < 0;
        b->max_index = x > b->max_index ? x : b->max_index;
    }
    free(inflated);
}

/* Skips one property at *at (type code included) within [.., limit); false when assimp's
 * tokenizer would throw. */
static bool skip_property(const fbx_bin *b, size_t *at, size_t limit)
{
    if (*at >= limit) {
        return false;
    }
    const char type = (char)b->data[(*at)++];
    uint64_t len = 0, enc = 0, comp = 0;
    switch (type) {
    case 'Y': len = 2; break;
    case 'C': len = 1; break;
    case 'I':
    case 'F': len = 4; break;
    case 'D':
    case 'L': len = 8; break;
    case 'R':
    case 'S':
        if (!read_uint(b, at, limit, 4, &len)) {
            return false;
        }
        break;
    case 'b': *at = limit; return true;
    case 'f':
    case 'd':
    case 'l':
    case 'i':
    case 'c':
        if (!read_uint(b, at, limit, 4, &len) || !read_uint(b, at, limit, 4, &enc) || !read_uint(b, at, limit, 4, &comp)) {
            return false;
        }
        if (enc == 0) {
            uint64_t stride = type == 'c' ? 1 : type == 'd' || type == 'l' ? 8 : 4;
            if ((uint32_t)(len * stride) != comp) {
                return false;
            }
        } else if (enc != 1) {
            return false;
        }
        len = comp;
        break;
    default:
        return false;
    }
    if (len > limit - *at) {
        return false;
    }
    *at += (size_t)len;
    return true;
}

/* One record at *at, ending no later than limit; false when the walk must stop. */
static bool walk_record(fbx_bin *b, size_t *at, size_t limit, uint32_t depth, bool *done)
{
    const int word = b->wide ? 8 : 4;
    uint64_t end_offset, props, prop_len, name_len;
    if (!read_uint(b, at, limit, word, &end_offset)) {
        return false;
    }
    if (end_offset == 0) {
        *done = true; /* the NUL record that closes a list */
        return true;
    }
    if (end_offset > limit || end_offset < *at || !read_uint(b, at, limit, word, &props) ||
        !read_uint(b, at, limit, word, &prop_len) || !read_uint(b, at, limit, 1, &name_len) || name_len > limit - *at) {
        return false;
    }
    const uint8_t *name = b->data + *at;
    *at += (size_t)name_len;
    if (prop_len > limit - *at) {
        return false;
    }
    const size_t prop_start = *at, prop_end = *at + (size_t)prop_len;
    const bool connection = name_len == 1 && name[0] == 'C';
    const bool vertices = name_len == 8 && memcmp(name, "Vertices", 8) == 0;
    const bool indexes = name_len == 7 && memcmp(name, "Indexes", 7) == 0;
    uint64_t id[2] = {0, 0};
    bool ids = connection && props >= 3, pp = false, oo = false;
    for (uint64_t i = 0; i < props; ++i) {
        size_t p = *at;
        if (!skip_property(b, at, prop_end)) {
            return false;
        }
        if (i == 0 && vertices && b->data[p] == 'd') { /* skin clusters index these control points */
            size_t q = p + 1;
            uint64_t len = 0;
            read_uint(b, &q, *at, 4, &len);
            b->control_points = (int64_t)(len / 3) > b->control_points ? (int64_t)(len / 3) : b->control_points;
        } else if (i == 0 && indexes && b->data[p] == 'i') {
            scan_index_array(b, p);
        }
        if (ids && i == 0) {
            pp = *at - p == 7 && b->data[p] == 'S' && memcmp(b->data + p + 5, "PP", 2) == 0;
            oo = !(*at - p == 7 && b->data[p] == 'S' && memcmp(b->data + p + 5, "OP", 2) == 0);
            ids = b->data[p] == 'S';
        } else if (ids && (i == 1 || i == 2)) {
            ids = b->data[p] == 'L' && *at - p == 9;
            if (ids) {
                size_t q = p + 1;
                read_uint(b, &q, *at, 8, &id[i - 1]);
            }
        }
    }
    if (*at - prop_start != prop_len) {
        return false;
    }
    if (ids && !pp && !links_add(b->links, id[0], id[1], oo)) {
        return false;
    }
    const size_t sentinel = b->wide ? 25 : 13;
    if (*at < end_offset) {
        if (end_offset - *at < sentinel) {
            return false;
        }
        if (depth + 1 > b->max_depth) {
            b->max_depth = depth + 1;
        }
        if (depth + 1 > CHECK_MAX_DEPTH) {
            return false; /* refused by the caller from max_depth */
        }
        const size_t inner = (size_t)end_offset - sentinel;
        while (*at < inner) {
            bool zero = false; /* a zero end offset inside a list: assimp reads on after it */
            if (!walk_record(b, at, inner, depth + 1, &zero)) {
                return false;
            }
        }
        *at = inner + sentinel;
    }
    return *at == end_offset;
}

/* Whether the records walk to their closing NUL record (or exactly to the end of the file):
 * assimp's own tokenizer refuses what stops earlier, or asserts and aborts on some of it (a
 * mangled header whose version made 64-bit records of 32-bit ones ran its cursor past the end). */
static bool walk_fbx_binary(fbx_bin *b)
{
    if (b->size < 27) {
        return false;
    }
    const uint32_t version = (uint32_t)b->data[23] | (uint32_t)b->data[24] << 8 | (uint32_t)b->data[25] << 16 |
                             (uint32_t)b->data[26] << 24;
    b->wide = version >= 7500;
    size_t at = 27;
    bool done = false;
    bool ok = true;
    while (ok && at < b->size && !done) {
        ok = walk_record(b, &at, b->size, 0, &done);
    }
    return ok && (done || at == b->size);
}

/* ---------------------------------------------------------------------------------------- */

static bool mentions_fbx(const char *path, const uint8_t *data, size_t size)
{
    const char *dot = strrchr(path, '.');
    if (dot && (dot[1] == 'f' || dot[1] == 'F') && (dot[2] == 'b' || dot[2] == 'B') && (dot[3] == 'x' || dot[3] == 'X') &&
        dot[4] == '\0') {
        return true;
    }
    for (size_t i = 0; i + 3 <= size && i < 200; ++i) { /* assimp's header search: 200 bytes */
        if ((data[i] | 0x20) == 'f' && (data[i + 1] | 0x20) == 'b' && (data[i + 2] | 0x20) == 'x') {
            return true;
        }
    }
    return false;
}

/* ASCII FBX: the largest control-point count of any geometry ("Vertices: *N", N / 3) and the
 * largest skin-cluster vertex index ("Indexes: *N { a: i, j, ... }"); false when a cluster names a
 * vertex beyond every geometry, or a negative one: assimp 5.2's converter asserts on it
 * (FBXConverter.cpp, out_idx != nullptr) and aborts the process. Binary FBX is not checked. */
/* The values of the `a:` array of the element whose key is at p, up to its closing '}', read as
 * assimp's tokenizer reads them: ';' comments to the end of the line, values between ',' and
 * blanks, each the leading integer of its token (0 when it has none, as assimp's strtol10).
 * Returns the count, or calls fn(value, user) for each while fn returns true. */
typedef bool ascii_value_fn(long long value, void *user);
static size_t ascii_array(const char *p, ascii_value_fn *fn, void *user)
{
    const char *a = strstr(p, "a:"), *end = strchr(p, '}');
    size_t n = 0;
    if (!a || !end || a > end) {
        return 0;
    }
    for (const char *q = a + 2; q < end;) {
        if (*q == ';') {
            while (q < end && *q != '\n' && *q != '\r') {
                ++q;
            }
            continue;
        }
        if (*q == ',' || fbx_space(*q)) {
            ++q;
            continue;
        }
        const char *t = q;
        while (q < end && *q != ',' && *q != ';' && !fbx_space(*q)) {
            ++q;
        }
        char *next = NULL;
        long long v = strtoll(t, &next, 10);
        v = next == t ? 0 : v;
        ++n;
        if (fn && !fn(v, user)) {
            break;
        }
    }
    return n;
}

typedef struct ascii_skin {
    size_t control_points;
    uint8_t *used; /* control point referenced by a polygon */
    bool bad;
} ascii_skin;

static bool mark_polygon_vertex(long long v, void *user)
{
    ascii_skin *k = user;
    const long long i = v < 0 ? -(v + 1) : v; /* a polygon's last index is stored as ~index */
    if (i < 0 || (size_t)i >= k->control_points) {
        k->bad = true;
        return false;
    }
    k->used[i] = 1;
    return true;
}

static bool check_cluster_index(long long v, void *user)
{
    ascii_skin *k = user;
    k->bad = v < 0 || (size_t)v >= k->control_points || !k->used[v];
    return !k->bad;
}

/* Skin cluster indices of an ASCII FBX: each must name a control point that a polygon uses, as
 * assimp's converter maps clusters through the polygons' vertices and asserts (aborting the
 * process) on one that maps to none; polygon indices must name control points. Arrays are read as
 * assimp reads them (ascii_array), so a ';' that comments out the end of a polygon list counts.
 * Control points: the most of any mesh's Vertices values / 3. false: refuse. */
static bool fbx_ascii_indices_ok(const char *text)
{
    ascii_skin k = {0, NULL, false};
    for (const char *p = text; (p = strstr(p, "Vertices:")) != NULL; ++p) {
        const size_t n = ascii_array(p, NULL, NULL) / 3;
        k.control_points = n > k.control_points ? n : k.control_points;
    }
    k.used = calloc(k.control_points ? k.control_points : 1, 1);
    if (!k.used) {
        return false;
    }
    for (const char *p = text; !k.bad && (p = strstr(p, "PolygonVertexIndex:")) != NULL; ++p) {
        ascii_array(p, mark_polygon_vertex, &k);
    }
    for (const char *p = text; !k.bad && (p = strstr(p, "Indexes:")) != NULL; ++p) {
        ascii_array(p, check_cluster_index, &k);
    }
    free(k.used);
    return !k.bad;
}

static weft_result check_fbx(const char *path, const uint8_t *data, size_t size)
{
    links l = {NULL, 0, 0, false, false};
    uint32_t depth = 0;
    if (size >= 18 && memcmp(data, "Kaydara FBX Binary", 18) == 0) {
        fbx_bin b = {data, size, false, 0, &l, 0, -1, false};
        b.max_index = -1;
        const bool walked = walk_fbx_binary(&b);
        depth = b.max_depth;
        if (!walked) {
            free(l.edge);
            return weft__fail(WEFT_ERROR_FORMAT,
                              "skinned mesh: '%s': the binary FBX records do not nest and end as the format says "
                              "(assimp 5.2 can abort on such files)",
                              path);
        }
        if (b.bad_index || b.max_index >= b.control_points) {
            free(l.edge);
            return weft__fail(WEFT_ERROR_FORMAT,
                              "skinned mesh: '%s': an FBX skin cluster names a vertex beyond the meshes' control "
                              "points, or its index array does not decode (assimp 5.2 would abort)",
                              path);
        }
    } else if (mentions_fbx(path, data, size)) {
        bool empty_key = false;
        walk_fbx_ascii((const char *)data, size, &depth, &l, &empty_key);
        if (empty_key) {
            free(l.edge);
            return weft__fail(WEFT_ERROR_FORMAT,
                              "skinned mesh: '%s': an FBX element has a key and no value (assimp 5.2 would free memory "
                              "twice)",
                              path);
        }
        if (!fbx_ascii_indices_ok((const char *)data)) {
            free(l.edge);
            return weft__fail(WEFT_ERROR_FORMAT,
                              "skinned mesh: '%s': an FBX skin cluster names a vertex no polygon uses, or a polygon "
                              "a vertex beyond the meshes' control points (assimp 5.2 would abort)",
                              path);
        }
    }
    weft_result res = WEFT_OK;
    if (depth > CHECK_MAX_DEPTH) {
        res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: '%s': FBX scopes nested deeper than %u levels", path,
                         CHECK_MAX_DEPTH);
    } else if (l.too_many) {
        res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: '%s': more than %u FBX connections", path,
                         CHECK_MAX_CONNECTIONS);
    } else {
        int cycle = l.out_of_memory ? -1 : links_cycle(&l);
        const int dup = cycle < 0 ? 0 : links_duplicate(&l);
        cycle = dup < 0 ? -1 : cycle;
        if (cycle < 0) {
            res = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "skinned mesh: out of memory checking '%s'", path);
        } else if (cycle) {
            res = weft__fail(WEFT_ERROR_FORMAT,
                             "skinned mesh: '%s': the FBX object connections form a cycle (assimp 5.2 would "
                             "recurse until the stack overflows)",
                             path);
        } else if (dup) {
            res = weft__fail(WEFT_ERROR_FORMAT,
                             "skinned mesh: '%s': an FBX object connection is listed twice (assimp 5.2 would free "
                             "memory twice)",
                             path);
        }
    }
    free(l.edge);
    return res;
}

weft_result weft__assimp_check_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "skinned mesh: cannot open '%s': %s", path, strerror(errno));
    }
    long size = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
    if (size < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        return weft__fail(WEFT_ERROR_IO, "skinned mesh: cannot read '%s'", path);
    }
    if ((uint64_t)size > CHECK_MAX_FILE_BYTES) {
        fclose(f);
        return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: '%s' holds more than %llu bytes", path,
                          (unsigned long long)CHECK_MAX_FILE_BYTES);
    }
    uint8_t *data = malloc((size_t)size + 1);
    if (!data) {
        fclose(f);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "skinned mesh: out of memory for %ld bytes", size);
    }
    bool read_ok = fread(data, 1, (size_t)size, f) == (size_t)size;
    fclose(f);
    if (!read_ok) {
        free(data);
        return weft__fail(WEFT_ERROR_IO, "skinned mesh: cannot read '%s'", path);
    }
    data[size] = 0;
    size_t json_len = 0;
    const char *bad_glb = NULL;
    const char *json = gltf_json(data, (size_t)size, &json_len, &bad_glb);
    weft_result res = WEFT_OK;
    /* ASCII FBX opens with its "; FBX x.y.z project file" comment or its first record; text that
     * merely mentions FBX somewhere (a Quick3D file did, and assimp's Q3D reader then asked for
     * 619 GB) is not FBX */
    size_t first = 0;
    while (first < (size_t)size && (data[first] == ' ' || data[first] == '\t' || data[first] == '\r' ||
                                    data[first] == '\n')) {
        first++;
    }
    const bool ascii_fbx = first < (size_t)size &&
                           (data[first] == ';' || strncmp((const char *)data + first, "FBXHeaderExtension", 18) == 0) &&
                           mentions_fbx(path, data, (size_t)size);
    const bool fbx = ((size_t)size >= 18 && memcmp(data, "Kaydara FBX Binary", 18) == 0) || ascii_fbx;
    if (bad_glb) {
        res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: '%s': %s", path, bad_glb);
    } else if (!json && !fbx) {
        /* assimp would try its other readers on it, and some of them never return on a few
         * bytes of noise: skinned characters come as glTF 2.0 or FBX */
        res = weft__fail(WEFT_ERROR_FORMAT,
                         "skinned mesh: '%s' is neither glTF 2.0 (JSON text or glb) nor FBX (binary, or ASCII "
                         "naming FBX)",
                         path);
    } else if (json) {
        res = check_gltf_json(path, json, json_len);
    }
    if (res == WEFT_OK) {
        res = check_fbx(path, data, (size_t)size);
    }
    free(data);
    return res;
}
