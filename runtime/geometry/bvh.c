/* Binary AABB tree over points, edges or triangles. Children are stored as adjacent pairs
 * after their parent, so a reverse sweep over the nodes refits bottom-up. */
#include "geometry/geometry.h"

#include <float.h>

#define XBVH_LEAF 4u

static uint32_t wide_collapse(geo_bvh *bvh, geo_bvh_wide *wide);

weft_result geo_bvh_create(const weft_context *ctx, geo_bvh *bvh, const uint32_t *prim_verts, uint32_t prim_count,
                        uint32_t arity)
{
    *bvh = (geo_bvh){0};
    bvh->prim_count = prim_count;
    bvh->arity = arity;
    bvh->prim_verts = prim_verts;
    if (prim_count == 0) {
        return WEFT_OK;
    }
    size_t max_nodes = 2 * (size_t)prim_count;
    bvh->order = weft__alloc(ctx, prim_count * sizeof(uint32_t));
    bvh->nodes = weft__alloc(ctx, max_nodes * sizeof(geo_bvh_node));
    bvh->build_stack = weft__alloc(ctx, 3 * max_nodes * sizeof(uint32_t));
    if (!bvh->order || !bvh->nodes || !bvh->build_stack) {
        geo_bvh_destroy(ctx, bvh);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    return WEFT_OK;
}

void geo_bvh_destroy(const weft_context *ctx, geo_bvh *bvh)
{
    weft__free(ctx, bvh->wide, (size_t)bvh->wide_count * sizeof(geo_bvh_wide));
    size_t max_nodes = 2 * (size_t)bvh->prim_count;
    weft__free(ctx, bvh->order, bvh->prim_count * sizeof(uint32_t));
    weft__free(ctx, bvh->nodes, max_nodes * sizeof(geo_bvh_node));
    weft__free(ctx, bvh->build_stack, 3 * max_nodes * sizeof(uint32_t));
    *bvh = (geo_bvh){0};
}

static double centroid(const geo_bvh *bvh, const double *pos, uint32_t prim, int axis)
{
    double s = 0.0;
    for (uint32_t k = 0; k < bvh->arity; ++k) {
        s += pos[3 * (size_t)bvh->prim_verts[bvh->arity * (size_t)prim + k] + axis];
    }
    return s / bvh->arity;
}

void geo_bvh_build(geo_bvh *bvh, const double *pos)
{
    if (bvh->prim_count == 0) {
        return;
    }
    for (uint32_t i = 0; i < bvh->prim_count; ++i) {
        bvh->order[i] = i;
    }
    uint32_t *stack = bvh->build_stack;
    uint32_t sp = 0;
    bvh->node_count = 1;
    stack[sp++] = 0, stack[sp++] = 0, stack[sp++] = bvh->prim_count;
    while (sp > 0) {
        uint32_t end = stack[--sp], begin = stack[--sp], node = stack[--sp];
        geo_bvh_node *nd = &bvh->nodes[node];
        uint32_t n = end - begin;
        if (n <= XBVH_LEAF) {
            nd->left = begin;
            nd->count = n;
            continue;
        }
        /* Widest axis of the centroid bounds. */
        double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX};
        for (uint32_t i = begin; i < end; ++i) {
            for (int a = 0; a < 3; ++a) {
                double c = centroid(bvh, pos, bvh->order[i], a);
                lo[a] = c < lo[a] ? c : lo[a];
                hi[a] = c > hi[a] ? c : hi[a];
            }
        }
        int axis = 0;
        for (int a = 1; a < 3; ++a) {
            if (hi[a] - lo[a] > hi[axis] - lo[axis]) {
                axis = a;
            }
        }
        /* Median split (quickselect): the tree depth stays log2(n), so queries never
         * overflow their fixed stack. */
        uint32_t split = begin + n / 2;
        uint32_t l = begin, r = end - 1;
        while (l < r) {
            double pivot = centroid(bvh, pos, bvh->order[(l + r) / 2], axis);
            uint32_t i = l, j = r;
            while (i <= j) {
                while (centroid(bvh, pos, bvh->order[i], axis) < pivot) {
                    ++i;
                }
                while (centroid(bvh, pos, bvh->order[j], axis) > pivot) {
                    --j;
                }
                if (i <= j) {
                    uint32_t t = bvh->order[i];
                    bvh->order[i] = bvh->order[j];
                    bvh->order[j] = t;
                    ++i;
                    if (j == 0) {
                        break;
                    }
                    --j;
                }
            }
            if (split <= j) {
                r = j;
            } else if (split >= i) {
                l = i;
            } else {
                break;
            }
        }
        uint32_t left = bvh->node_count;
        bvh->node_count += 2;
        nd->left = left;
        nd->count = 0;
        stack[sp++] = left, stack[sp++] = begin, stack[sp++] = split;
        stack[sp++] = left + 1, stack[sp++] = split, stack[sp++] = end;
    }
    if (bvh->wide) {
        /* The median split gives the same shape for the same count: the view keeps its size; its
         * boxes come with the next refit. */
        wide_collapse(bvh, bvh->wide);
    }
}

/* The binary nodes under binary interior node n that one wide node holds: its children, each
 * interior one opened once more while lanes are free (grandchildren of a balanced tree). */
static uint32_t wide_lanes(const geo_bvh *bvh, uint32_t n, uint32_t lanes[4])
{
    uint32_t count = 2;
    lanes[0] = bvh->nodes[n].left;
    lanes[1] = bvh->nodes[n].left + 1;
    for (uint32_t i = 0, end = count; i < end && count < 4; ++i) {
        const geo_bvh_node *c = &bvh->nodes[lanes[i]];
        if (c->count == 0) {
            lanes[count++] = c->left + 1;
            lanes[i] = c->left;
        }
    }
    return count;
}

/* Lays the wide nodes out from the binary tree (wide == NULL: counts them). The root's wide node
 * is 0; a binary root that is a leaf gets one lane. Uses the build stack. */
static uint32_t wide_collapse(geo_bvh *bvh, geo_bvh_wide *wide)
{
    if (bvh->node_count == 0) {
        return 0;
    }
    uint32_t *stack = bvh->build_stack, sp = 0, count = 1;
    stack[sp++] = 0, stack[sp++] = 0; /* (wide node, binary node) */
    while (sp > 0) {
        const uint32_t n = stack[--sp], w = stack[--sp];
        uint32_t lanes[4], used = 1;
        if (bvh->nodes[n].count > 0) {
            lanes[0] = n; /* the root is a leaf */
        } else {
            used = wide_lanes(bvh, n, lanes);
        }
        for (uint32_t l = 0; l < 4; ++l) {
            uint32_t child = UINT32_MAX;
            if (l < used) {
                if (bvh->nodes[lanes[l]].count > 0) {
                    child = GEO_BVH_WIDE_LEAF | lanes[l];
                } else {
                    child = count++;
                    stack[sp++] = child, stack[sp++] = lanes[l];
                }
            }
            if (wide) {
                wide[w].src[l] = l < used ? lanes[l] : UINT32_MAX;
                wide[w].child[l] = child;
                for (int a = 0; a < 3; ++a) {
                    wide[w].lo[a][l] = DBL_MAX;
                    wide[w].hi[a][l] = -DBL_MAX;
                }
            }
        }
    }
    return count;
}

weft_result geo_bvh_wide_create(const weft_context *ctx, geo_bvh *bvh)
{
    if (bvh->wide || bvh->node_count == 0 || bvh->prim_count >= GEO_BVH_WIDE_LEAF / 2) {
        return WEFT_OK; /* made already, nothing to hold, or past the leaf flag (binary walk) */
    }
    const uint32_t count = wide_collapse(bvh, NULL);
    bvh->wide = weft__alloc(ctx, (size_t)count * sizeof(geo_bvh_wide));
    if (!bvh->wide) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    bvh->wide_count = count;
    wide_collapse(bvh, bvh->wide);
    for (uint32_t w = 0; w < count; ++w) { /* the boxes the binary tree has now */
        for (uint32_t l = 0; l < 4; ++l) {
            const uint32_t s = bvh->wide[w].src[l];
            for (int a = 0; s != UINT32_MAX && a < 3; ++a) {
                bvh->wide[w].lo[a][l] = bvh->nodes[s].lo[a];
                bvh->wide[w].hi[a][l] = bvh->nodes[s].hi[a];
            }
        }
    }
    return WEFT_OK;
}

void geo_bvh_refit(geo_bvh *bvh, const double *pos0, const double *pos1, double pad)
{
    for (uint32_t ni = bvh->node_count; ni-- > 0;) {
        geo_bvh_node *nd = &bvh->nodes[ni];
        double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX};
        uint32_t max_prim = 0;
        if (nd->count > 0) {
            for (uint32_t s = nd->left; s < nd->left + nd->count; ++s) {
                max_prim = bvh->order[s] > max_prim ? bvh->order[s] : max_prim;
                const uint32_t *pv = bvh->prim_verts + bvh->arity * (size_t)bvh->order[s];
                for (uint32_t k = 0; k < bvh->arity; ++k) {
                    for (int pass = 0; pass < (pos1 ? 2 : 1); ++pass) {
                        const double *p = (pass ? pos1 : pos0) + 3 * (size_t)pv[k];
                        for (int a = 0; a < 3; ++a) {
                            lo[a] = p[a] < lo[a] ? p[a] : lo[a];
                            hi[a] = p[a] > hi[a] ? p[a] : hi[a];
                        }
                    }
                }
            }
            for (int a = 0; a < 3; ++a) {
                lo[a] -= pad;
                hi[a] += pad;
            }
        } else {
            const geo_bvh_node *l = &bvh->nodes[nd->left], *r = &bvh->nodes[nd->left + 1];
            max_prim = l->max_prim > r->max_prim ? l->max_prim : r->max_prim;
            for (int a = 0; a < 3; ++a) {
                lo[a] = l->lo[a] < r->lo[a] ? l->lo[a] : r->lo[a];
                hi[a] = l->hi[a] > r->hi[a] ? l->hi[a] : r->hi[a];
            }
        }
        for (int a = 0; a < 3; ++a) {
            nd->lo[a] = lo[a];
            nd->hi[a] = hi[a];
        }
        nd->max_prim = max_prim;
    }
    for (uint32_t w = 0; w < bvh->wide_count; ++w) {
        geo_bvh_wide *wn = &bvh->wide[w];
        for (uint32_t l = 0; l < 4; ++l) {
            const uint32_t s = wn->src[l];
            for (int a = 0; s != UINT32_MAX && a < 3; ++a) {
                wn->lo[a][l] = bvh->nodes[s].lo[a];
                wn->hi[a][l] = bvh->nodes[s].hi[a];
            }
        }
    }
}

/* all: visit every primitive; else only those with an index above `above`. */
static inline bool query(const geo_bvh *bvh, const double lo[3], const double hi[3], bool all, uint32_t above,
                         geo_bvh_visit_fn *fn, void *user)
{
    if (bvh->node_count == 0) {
        return true;
    }
    uint32_t stack[128];
    uint32_t sp = 0;
    stack[sp++] = 0;
    while (sp > 0) {
        const geo_bvh_node *nd = &bvh->nodes[stack[--sp]];
        if (nd->lo[0] > hi[0] || nd->hi[0] < lo[0] || nd->lo[1] > hi[1] || nd->hi[1] < lo[1] || nd->lo[2] > hi[2] ||
            nd->hi[2] < lo[2] || (!all && nd->max_prim <= above)) {
            continue;
        }
        if (nd->count > 0) {
            for (uint32_t s = nd->left; s < nd->left + nd->count; ++s) {
                if ((all || bvh->order[s] > above) && !fn(bvh->order[s], user)) {
                    return false;
                }
            }
        } else {
            stack[sp++] = nd->left;
            stack[sp++] = nd->left + 1;
        }
    }
    return true;
}

bool geo_bvh_query(const geo_bvh *bvh, const double lo[3], const double hi[3], geo_bvh_visit_fn *fn, void *user)
{
    return query(bvh, lo, hi, true, 0, fn, user);
}

bool geo_bvh_query_above(const geo_bvh *bvh, const double lo[3], const double hi[3], uint32_t above, geo_bvh_visit_fn *fn,
                      void *user)
{
    return query(bvh, lo, hi, false, above, fn, user);
}

/* Squared distance from p to the node's box (0 inside). */
static inline double box_d2(const geo_bvh_node *nd, const double p[3])
{
    double d2 = 0.0;
    for (int a = 0; a < 3; ++a) {
        const double e = p[a] < nd->lo[a] ? nd->lo[a] - p[a] : (p[a] > nd->hi[a] ? p[a] - nd->hi[a] : 0.0);
        d2 += e * e;
    }
    return d2;
}

/* geo_bvh_nearest on the wide view: the four lanes' distances in one pass (no branches, so the
 * compiler may vectorise it), the lanes within the bound pushed farthest first. */
static bool nearest_wide(const geo_bvh *bvh, const double p[3], const double *bound_d2, geo_bvh_visit_fn *fn,
                         void *user)
{
    uint32_t stack[128]; /* 3 a level and one: a wide level is at least one binary level (at most 32) */
    double dist[128];
    uint32_t sp = 0;
    stack[sp] = 0;
    dist[sp++] = 0.0;
    while (sp > 0) {
        --sp;
        if (dist[sp] > *bound_d2) {
            continue; /* farther than the best found since it was pushed */
        }
        const uint32_t ref = stack[sp];
        if (ref & GEO_BVH_WIDE_LEAF) {
            const geo_bvh_node *nd = &bvh->nodes[ref & ~GEO_BVH_WIDE_LEAF];
            for (uint32_t s = nd->left; s < nd->left + nd->count; ++s) {
                if (!fn(bvh->order[s], user)) {
                    return false;
                }
            }
            continue;
        }
        const geo_bvh_wide *w = &bvh->wide[ref];
        double d[4] = {0.0, 0.0, 0.0, 0.0};
        for (int a = 0; a < 3; ++a) {
            for (int l = 0; l < 4; ++l) {
                const double below = w->lo[a][l] - p[a], above = p[a] - w->hi[a][l];
                double e = below > above ? below : above;
                e = e > 0.0 ? e : 0.0;
                d[l] += e * e;
            }
        }
        /* the lanes within the bound, nearest last (on top of the stack) */
        uint32_t order[4], n = 0;
        const double bound = *bound_d2;
        for (uint32_t l = 0; l < 4; ++l) {
            if (w->child[l] == UINT32_MAX || d[l] > bound) {
                continue;
            }
            uint32_t i = n++;
            for (; i > 0 && d[order[i - 1]] < d[l]; --i) {
                order[i] = order[i - 1];
            }
            order[i] = l;
        }
        for (uint32_t i = 0; i < n; ++i) {
            stack[sp] = w->child[order[i]];
            dist[sp++] = d[order[i]];
        }
    }
    return true;
}

bool geo_bvh_nearest(const geo_bvh *bvh, const double p[3], const double *bound_d2, geo_bvh_visit_fn *fn, void *user)
{
    if (bvh->node_count == 0) {
        return true;
    }
    if (bvh->wide) {
        return nearest_wide(bvh, p, bound_d2, fn, user);
    }
    uint32_t stack[128];
    double dist[128];
    uint32_t sp = 0;
    stack[sp] = 0;
    dist[sp++] = box_d2(&bvh->nodes[0], p);
    while (sp > 0) {
        --sp;
        if (dist[sp] > *bound_d2) {
            continue; /* farther than the best found since it was pushed */
        }
        const geo_bvh_node *nd = &bvh->nodes[stack[sp]];
        if (nd->count > 0) {
            for (uint32_t s = nd->left; s < nd->left + nd->count; ++s) {
                if (!fn(bvh->order[s], user)) {
                    return false;
                }
            }
            continue;
        }
        /* the nearer child on top, so it is opened first and tightens the bound */
        const uint32_t a = nd->left, b = nd->left + 1;
        const double da = box_d2(&bvh->nodes[a], p), db = box_d2(&bvh->nodes[b], p);
        const uint32_t first = da <= db ? b : a, second = da <= db ? a : b;
        const double dfirst = da <= db ? db : da, dsecond = da <= db ? da : db;
        if (dfirst <= *bound_d2) {
            stack[sp] = first;
            dist[sp++] = dfirst;
        }
        if (dsecond <= *bound_d2) {
            stack[sp] = second;
            dist[sp++] = dsecond;
        }
    }
    return true;
}

static inline bool nodes_meet(const geo_bvh_node *a, const geo_bvh_node *b)
{
    return !(a->lo[0] > b->hi[0] || b->lo[0] > a->hi[0] || a->lo[1] > b->hi[1] || b->lo[1] > a->hi[1] ||
             a->lo[2] > b->hi[2] || b->lo[2] > a->hi[2]);
}

static double node_extent(const geo_bvh_node *n)
{
    return (n->hi[0] - n->lo[0]) + (n->hi[1] - n->lo[1]) + (n->hi[2] - n->lo[2]);
}

/* Nodes a and b (a == b: the pairs inside one subtree). Recursion depth is at most twice the
 * tree's, which the median split keeps at log2 of the leaf count. */
static void self_pairs(const geo_bvh *bvh, uint32_t a, uint32_t b, geo_bvh_pair_fn *fn, void *user)
{
    const geo_bvh_node *na = &bvh->nodes[a], *nb = &bvh->nodes[b];
    if (a == b) {
        if (na->count > 0) {
            for (uint32_t i = na->left; i < na->left + na->count; ++i) {
                for (uint32_t j = i + 1; j < na->left + na->count; ++j) {
                    fn(bvh->order[i], bvh->order[j], user);
                }
            }
        } else {
            self_pairs(bvh, na->left, na->left, fn, user);
            self_pairs(bvh, na->left + 1, na->left + 1, fn, user);
            self_pairs(bvh, na->left, na->left + 1, fn, user);
        }
        return;
    }
    if (!nodes_meet(na, nb)) {
        return;
    }
    if (na->count > 0 && nb->count > 0) {
        for (uint32_t i = na->left; i < na->left + na->count; ++i) {
            for (uint32_t j = nb->left; j < nb->left + nb->count; ++j) {
                fn(bvh->order[i], bvh->order[j], user);
            }
        }
    } else if (nb->count > 0 || (na->count == 0 && node_extent(na) >= node_extent(nb))) {
        self_pairs(bvh, na->left, b, fn, user);
        self_pairs(bvh, na->left + 1, b, fn, user);
    } else {
        self_pairs(bvh, a, nb->left, fn, user);
        self_pairs(bvh, a, nb->left + 1, fn, user);
    }
}

void geo_bvh_self_pairs(const geo_bvh *bvh, geo_bvh_pair_fn *fn, void *user)
{
    if (bvh->node_count > 0) {
        self_pairs(bvh, 0, 0, fn, user);
    }
}
