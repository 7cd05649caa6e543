/* Binary AABB tree over points, edges or triangles. Children are stored as adjacent pairs
 * after their parent, so a reverse sweep over the nodes refits bottom-up. */
#include "geometry/geometry.h"

#include <float.h>

#define XBVH_LEAF 4u

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

bool geo_bvh_nearest(const geo_bvh *bvh, const double p[3], const double *bound_d2, geo_bvh_visit_fn *fn, void *user)
{
    if (bvh->node_count == 0) {
        return true;
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
