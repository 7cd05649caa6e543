/* Exact decision procedure for CCD queries with GMP rationals.
 *
 * Every input double is an exact rational, so each coordinate is a rational polynomial of degree 1
 * in t and every contact condition is a sign condition on a rational polynomial of degree <= 4:
 *   VF: (f = 0, |n|^2 > 0, three barycentric numerators >= 0), or p on a closed edge, or p equal to
 *       a corner (the edge and corner terms also cover degenerate triangles);
 *   EE: (f = 0, |ea x eb|^2 > 0, both line parameters in [0, 1]), or an end point on the other
 *       closed segment, or two end points equal (this covers parallel and collinear edges).
 * A conjunction is decided exactly: with an equation, at the real roots of that polynomial in
 * [0, 1] (isolated with Sturm sequences); without one, at 0, 1, every root of every polynomial and
 * just to the right of each (sign of the first non-vanishing derivative). The sign of a polynomial
 * at an algebraic root uses the gcd with the root's square-free polynomial, then interval
 * refinement until the polynomial has no root left in the isolating interval. */
#include "oracle.h"

#include <gmp.h>
#include <string.h>

#define NC 9 /* coefficients: degree <= 8 */

typedef struct qp {
    mpq_t c[NC];
    int deg; /* -1: zero polynomial */
} qp;

static void qp_init(qp *p)
{
    for (int i = 0; i < NC; ++i) {
        mpq_init(p->c[i]);
    }
    p->deg = -1;
}

static void qp_clear(qp *p)
{
    for (int i = 0; i < NC; ++i) {
        mpq_clear(p->c[i]);
    }
}

static void qp_norm(qp *p)
{
    p->deg = -1;
    for (int i = NC - 1; i >= 0; --i) {
        if (mpq_sgn(p->c[i]) != 0) {
            p->deg = i;
            return;
        }
    }
}

static void qp_copy(qp *d, const qp *s)
{
    for (int i = 0; i < NC; ++i) {
        mpq_set(d->c[i], s->c[i]);
    }
    d->deg = s->deg;
}

static void qp_zero(qp *p)
{
    for (int i = 0; i < NC; ++i) {
        mpq_set_ui(p->c[i], 0, 1);
    }
    p->deg = -1;
}

static void qp_add(qp *d, const qp *a, const qp *b)
{
    for (int i = 0; i < NC; ++i) {
        mpq_add(d->c[i], a->c[i], b->c[i]);
    }
    qp_norm(d);
}

static void qp_sub(qp *d, const qp *a, const qp *b)
{
    for (int i = 0; i < NC; ++i) {
        mpq_sub(d->c[i], a->c[i], b->c[i]);
    }
    qp_norm(d);
}

static void qp_mul(qp *d, const qp *a, const qp *b)
{
    qp r;
    qp_init(&r);
    mpq_t t;
    mpq_init(t);
    for (int i = 0; i <= a->deg; ++i) {
        for (int j = 0; j <= b->deg && i + j < NC; ++j) {
            mpq_mul(t, a->c[i], b->c[j]);
            mpq_add(r.c[i + j], r.c[i + j], t);
        }
    }
    qp_norm(&r);
    qp_copy(d, &r);
    mpq_clear(t);
    qp_clear(&r);
}

static void qp_deriv(qp *d, const qp *a)
{
    qp r;
    qp_init(&r);
    mpq_t k;
    mpq_init(k);
    for (int i = 1; i <= a->deg; ++i) {
        mpq_set_ui(k, (unsigned long)i, 1);
        mpq_mul(r.c[i - 1], a->c[i], k);
    }
    qp_norm(&r);
    qp_copy(d, &r);
    mpq_clear(k);
    qp_clear(&r);
}

static int qp_sign_at(const qp *p, const mpq_t x)
{
    if (p->deg < 0) {
        return 0;
    }
    mpq_t acc;
    mpq_init(acc);
    mpq_set(acc, p->c[p->deg]);
    for (int i = p->deg - 1; i >= 0; --i) {
        mpq_mul(acc, acc, x);
        mpq_add(acc, acc, p->c[i]);
    }
    int s = mpq_sgn(acc);
    mpq_clear(acc);
    return s;
}

/* q = a / b, r = a mod b (b non-zero); q may be NULL. */
static void qp_divmod(qp *q, qp *r, const qp *a, const qp *b)
{
    qp rem, quo;
    qp_init(&rem);
    qp_init(&quo);
    qp_copy(&rem, a);
    mpq_t f, t;
    mpq_init(f);
    mpq_init(t);
    while (rem.deg >= b->deg && rem.deg >= 0) {
        int shift = rem.deg - b->deg;
        mpq_div(f, rem.c[rem.deg], b->c[b->deg]);
        mpq_set(quo.c[shift], f);
        for (int i = 0; i <= b->deg; ++i) {
            mpq_mul(t, f, b->c[i]);
            mpq_sub(rem.c[i + shift], rem.c[i + shift], t);
        }
        mpq_set_ui(rem.c[rem.deg], 0, 1);
        qp_norm(&rem);
    }
    qp_norm(&quo);
    if (q) {
        qp_copy(q, &quo);
    }
    qp_copy(r, &rem);
    mpq_clear(f);
    mpq_clear(t);
    qp_clear(&rem);
    qp_clear(&quo);
}

static void qp_gcd(qp *g, const qp *a, const qp *b)
{
    qp x, y, r;
    qp_init(&x);
    qp_init(&y);
    qp_init(&r);
    qp_copy(&x, a);
    qp_copy(&y, b);
    while (y.deg >= 0) {
        qp_divmod(NULL, &r, &x, &y);
        qp_copy(&x, &y);
        qp_copy(&y, &r);
    }
    if (x.deg >= 0) { /* monic */
        mpq_t lead;
        mpq_init(lead);
        mpq_set(lead, x.c[x.deg]);
        for (int i = 0; i <= x.deg; ++i) {
            mpq_div(x.c[i], x.c[i], lead);
        }
        mpq_clear(lead);
    }
    qp_copy(g, &x);
    qp_clear(&x);
    qp_clear(&y);
    qp_clear(&r);
}

/* Square-free part of a non-zero polynomial. */
static void qp_sqfree(qp *s, const qp *p)
{
    qp d, g;
    qp_init(&d);
    qp_init(&g);
    qp_deriv(&d, p);
    if (d.deg < 0) {
        qp_copy(s, p);
    } else {
        qp_gcd(&g, p, &d);
        qp r;
        qp_init(&r);
        qp_divmod(s, &r, p, &g);
        qp_clear(&r);
    }
    qp_clear(&d);
    qp_clear(&g);
}

/* ---- Sturm sequences ---------------------------------------------------------------------- */

typedef struct sturm {
    qp s[NC + 1];
    int n;
} sturm;

static void sturm_build(sturm *st, const qp *p)
{
    for (int i = 0; i < NC + 1; ++i) {
        qp_init(&st->s[i]);
    }
    qp_copy(&st->s[0], p);
    qp_deriv(&st->s[1], p);
    st->n = st->s[1].deg >= 0 ? 2 : 1;
    while (st->n >= 2 && st->s[st->n - 1].deg > 0 && st->n < NC + 1) {
        qp r;
        qp_init(&r);
        qp_divmod(NULL, &r, &st->s[st->n - 2], &st->s[st->n - 1]);
        if (r.deg < 0) {
            qp_clear(&r);
            break;
        }
        for (int i = 0; i < NC; ++i) {
            mpq_neg(r.c[i], r.c[i]);
        }
        qp_copy(&st->s[st->n], &r);
        st->n++;
        qp_clear(&r);
    }
}

static void sturm_free(sturm *st)
{
    for (int i = 0; i < NC + 1; ++i) {
        qp_clear(&st->s[i]);
    }
}

static int variations(const sturm *st, const mpq_t x)
{
    int v = 0, last = 0;
    for (int i = 0; i < st->n; ++i) {
        int s = qp_sign_at(&st->s[i], x);
        if (s != 0) {
            if (last != 0 && s != last) {
                v++;
            }
            last = s;
        }
    }
    return v;
}

/* Distinct roots of the square-free polynomial in (l, r]. */
static int count_roots(const sturm *st, const mpq_t l, const mpq_t r) { return variations(st, l) - variations(st, r); }

/* ---- roots --------------------------------------------------------------------------------- */

typedef struct root {
    bool exact;
    mpq_t lo, hi; /* exact: lo is the root; else the root is inside (lo, hi), Q(lo), Q(hi) != 0 */
} root;

#define MAXROOTS 8

typedef struct rootset {
    qp q; /* square-free */
    sturm st;
    root r[MAXROOTS];
    int n;
} rootset;

static void push_root(rootset *rs, const mpq_t lo, const mpq_t hi, bool exact)
{
    root *x = &rs->r[rs->n++];
    mpq_init(x->lo);
    mpq_init(x->hi);
    mpq_set(x->lo, lo);
    mpq_set(x->hi, hi);
    x->exact = exact;
}

static void isolate(rootset *rs, const mpq_t l, const mpq_t r, int count)
{
    if (count <= 0 || rs->n >= MAXROOTS) {
        return;
    }
    if (count == 1) {
        if (qp_sign_at(&rs->q, r) == 0) {
            push_root(rs, r, r, true);
            return;
        }
        mpq_t lo, hi, m, two;
        mpq_inits(lo, hi, m, two, NULL);
        mpq_set(lo, l);
        mpq_set(hi, r);
        mpq_set_ui(two, 2, 1);
        while (qp_sign_at(&rs->q, lo) == 0) { /* l is a root counted on its left: shrink */
            mpq_add(m, lo, hi);
            mpq_div(m, m, two);
            if (qp_sign_at(&rs->q, m) == 0) {
                if (count_roots(&rs->st, lo, m) == 1) {
                    push_root(rs, m, m, true);
                    mpq_clears(lo, hi, m, two, NULL);
                    return;
                }
                mpq_set(lo, m);
                continue;
            }
            if (count_roots(&rs->st, lo, m) == 1) {
                mpq_set(hi, m);
            } else {
                mpq_set(lo, m);
            }
        }
        push_root(rs, lo, hi, false);
        mpq_clears(lo, hi, m, two, NULL);
        return;
    }
    mpq_t m, two;
    mpq_inits(m, two, NULL);
    mpq_set_ui(two, 2, 1);
    mpq_add(m, l, r);
    mpq_div(m, m, two);
    int left = count_roots(&rs->st, l, m);
    isolate(rs, l, m, left);
    isolate(rs, m, r, count - left);
    mpq_clears(m, two, NULL);
}

/* Roots of non-zero, non-constant p in [0, 1], increasing. */
static void rootset_make(rootset *rs, const qp *p)
{
    qp_init(&rs->q);
    qp_sqfree(&rs->q, p);
    sturm_build(&rs->st, &rs->q);
    rs->n = 0;
    mpq_t zero, one;
    mpq_inits(zero, one, NULL);
    mpq_set_ui(one, 1, 1);
    if (qp_sign_at(&rs->q, zero) == 0) {
        push_root(rs, zero, zero, true);
    }
    isolate(rs, zero, one, count_roots(&rs->st, zero, one));
    mpq_clears(zero, one, NULL);
}

static void rootset_free(rootset *rs)
{
    for (int i = 0; i < rs->n; ++i) {
        mpq_clears(rs->r[i].lo, rs->r[i].hi, NULL);
    }
    sturm_free(&rs->st);
    qp_clear(&rs->q);
}

/* Exact sign of p at root x of rs->q (x's interval may be refined). */
static int sign_at_root(const qp *p, rootset *rs, root *x)
{
    if (p->deg < 0) {
        return 0;
    }
    if (x->exact) {
        return qp_sign_at(p, x->lo);
    }
    qp g;
    qp_init(&g);
    qp_gcd(&g, p, &rs->q);
    if (g.deg >= 1 && qp_sign_at(&g, x->lo) * qp_sign_at(&g, x->hi) < 0) {
        qp_clear(&g);
        return 0;
    }
    qp_clear(&g);
    qp s;
    qp_init(&s);
    qp_sqfree(&s, p);
    sturm ps;
    sturm_build(&ps, &s);
    mpq_t m, two;
    mpq_inits(m, two, NULL);
    mpq_set_ui(two, 2, 1);
    int sign = 0;
    for (;;) {
        if (s.deg <= 0 || count_roots(&ps, x->lo, x->hi) == 0) {
            sign = qp_sign_at(p, x->hi);
            break;
        }
        mpq_add(m, x->lo, x->hi);
        mpq_div(m, m, two);
        int sm = qp_sign_at(&rs->q, m);
        if (sm == 0) {
            x->exact = true;
            mpq_set(x->lo, m);
            mpq_set(x->hi, m);
            sign = qp_sign_at(p, m);
            break;
        }
        if (sm != qp_sign_at(&rs->q, x->lo)) {
            mpq_set(x->hi, m);
        } else {
            mpq_set(x->lo, m);
        }
    }
    mpq_clears(m, two, NULL);
    sturm_free(&ps);
    qp_clear(&s);
    return sign;
}

/* Sign just to the right of the root: first non-vanishing derivative. */
static int sign_right_of_root(const qp *p, rootset *rs, root *x)
{
    qp d;
    qp_init(&d);
    qp_copy(&d, p);
    int s = 0;
    while (d.deg >= 0) {
        s = sign_at_root(&d, rs, x);
        if (s != 0) {
            break;
        }
        qp_deriv(&d, &d);
    }
    qp_clear(&d);
    return s;
}

static int sign_right_of_point(const qp *p, const mpq_t x)
{
    qp d;
    qp_init(&d);
    qp_copy(&d, p);
    int s = 0;
    while (d.deg >= 0) {
        s = qp_sign_at(&d, x);
        if (s != 0) {
            break;
        }
        qp_deriv(&d, &d);
    }
    qp_clear(&d);
    return s;
}

/* ---- conjunctions ----------------------------------------------------------------------------- */

typedef enum rel { EQ, GT, GE } rel;

typedef struct cond {
    qp p;
    rel r;
} cond;

static bool holds(rel r, int s) { return r == EQ ? s == 0 : (r == GT ? s > 0 : s >= 0); }

/* Is there t in [0, 1] where every condition holds? */
static bool exists_t(cond *c, int n)
{
    int eq = -1;
    for (int i = 0; i < n; ++i) {
        if (c[i].r == EQ && c[i].p.deg >= 0) {
            eq = i;
            break;
        }
        if (c[i].r == GT && c[i].p.deg < 0) {
            return false;
        }
    }
    if (eq >= 0) {
        if (c[eq].p.deg == 0) {
            return false;
        }
        rootset rs;
        rootset_make(&rs, &c[eq].p);
        bool found = false;
        for (int k = 0; k < rs.n && !found; ++k) {
            bool all = true;
            for (int i = 0; i < n && all; ++i) {
                all = holds(c[i].r, sign_at_root(&c[i].p, &rs, &rs.r[k]));
            }
            found = all;
        }
        rootset_free(&rs);
        return found;
    }
    /* Only inequalities: test 0, just right of 0, 1, every root and just right of it. */
    mpq_t zero, one;
    mpq_inits(zero, one, NULL);
    mpq_set_ui(one, 1, 1);
    bool found = false;
    bool at0 = true, right0 = true, at1 = true;
    for (int i = 0; i < n; ++i) {
        at0 = at0 && holds(c[i].r, qp_sign_at(&c[i].p, zero));
        right0 = right0 && holds(c[i].r, sign_right_of_point(&c[i].p, zero));
        at1 = at1 && holds(c[i].r, qp_sign_at(&c[i].p, one));
    }
    found = at0 || right0 || at1;
    for (int j = 0; j < n && !found; ++j) {
        if (c[j].p.deg < 1) {
            continue;
        }
        rootset rs;
        rootset_make(&rs, &c[j].p);
        for (int k = 0; k < rs.n && !found; ++k) {
            bool all = true, right = true;
            for (int i = 0; i < n; ++i) {
                all = all && holds(c[i].r, sign_at_root(&c[i].p, &rs, &rs.r[k]));
                right = right && holds(c[i].r, sign_right_of_root(&c[i].p, &rs, &rs.r[k]));
            }
            /* Right of a root at 1 is outside [0, 1]. */
            bool at_one = rs.r[k].exact && mpq_cmp(rs.r[k].lo, one) == 0;
            found = all || (right && !at_one);
        }
        rootset_free(&rs);
    }
    mpq_clears(zero, one, NULL);
    return found;
}

/* ---- geometry ------------------------------------------------------------------------------- */

typedef struct qv {
    qp x[3];
} qv;

static void qv_init(qv *v)
{
    for (int k = 0; k < 3; ++k) {
        qp_init(&v->x[k]);
    }
}

static void qv_clear(qv *v)
{
    for (int k = 0; k < 3; ++k) {
        qp_clear(&v->x[k]);
    }
}

static void qv_point(qv *v, const double *P, int i)
{
    mpq_t a, b;
    mpq_inits(a, b, NULL);
    for (int k = 0; k < 3; ++k) {
        mpq_set_d(a, P[3 * i + k]);
        mpq_set_d(b, P[12 + 3 * i + k]);
        qp_zero(&v->x[k]);
        mpq_set(v->x[k].c[0], a);
        mpq_sub(v->x[k].c[1], b, a);
        qp_norm(&v->x[k]);
    }
    mpq_clears(a, b, NULL);
}

static void qv_sub(qv *d, const qv *a, const qv *b)
{
    for (int k = 0; k < 3; ++k) {
        qp_sub(&d->x[k], &a->x[k], &b->x[k]);
    }
}

static void qv_dot(qp *d, const qv *a, const qv *b)
{
    qp t, acc;
    qp_init(&t);
    qp_init(&acc);
    for (int k = 0; k < 3; ++k) {
        qp_mul(&t, &a->x[k], &b->x[k]);
        qp_add(&acc, &acc, &t);
    }
    qp_copy(d, &acc);
    qp_clear(&t);
    qp_clear(&acc);
}

static void qv_cross(qv *d, const qv *a, const qv *b)
{
    qv r;
    qv_init(&r);
    qp t1, t2;
    qp_init(&t1);
    qp_init(&t2);
    for (int k = 0; k < 3; ++k) {
        int i = (k + 1) % 3, j = (k + 2) % 3;
        qp_mul(&t1, &a->x[i], &b->x[j]);
        qp_mul(&t2, &a->x[j], &b->x[i]);
        qp_sub(&r.x[k], &t1, &t2);
    }
    for (int k = 0; k < 3; ++k) {
        qp_copy(&d->x[k], &r.x[k]);
    }
    qp_clear(&t1);
    qp_clear(&t2);
    qv_clear(&r);
}

typedef struct conj {
    cond c[8];
    int n;
} conj;

static void conj_init(conj *j)
{
    for (int i = 0; i < 8; ++i) {
        qp_init(&j->c[i].p);
    }
    j->n = 0;
}

static void conj_free(conj *j)
{
    for (int i = 0; i < 8; ++i) {
        qp_clear(&j->c[i].p);
    }
}

static void conj_add(conj *j, const qp *p, rel r)
{
    qp_copy(&j->c[j->n].p, p);
    j->c[j->n].r = r;
    j->n++;
}

/* p equals a at some t. */
static bool point_point(const qv *p, const qv *a)
{
    conj j;
    conj_init(&j);
    qv d;
    qv_init(&d);
    qv_sub(&d, p, a);
    for (int k = 0; k < 3; ++k) {
        conj_add(&j, &d.x[k], EQ);
    }
    bool r = exists_t(j.c, j.n);
    qv_clear(&d);
    conj_free(&j);
    return r;
}

/* p on the closed, non-degenerate segment ab at some t. */
static bool point_edge(const qv *p, const qv *a, const qv *b)
{
    conj j;
    conj_init(&j);
    qv pa, ba, pb, x;
    qv_init(&pa);
    qv_init(&ba);
    qv_init(&pb);
    qv_init(&x);
    qv_sub(&pa, p, a);
    qv_sub(&ba, b, a);
    qv_sub(&pb, p, b);
    qv_cross(&x, &pa, &ba);
    for (int k = 0; k < 3; ++k) {
        conj_add(&j, &x.x[k], EQ);
    }
    qp t;
    qp_init(&t);
    qv_dot(&t, &pa, &ba);
    conj_add(&j, &t, GE);
    qv_dot(&t, &pb, &ba);
    for (int i = 0; i < NC; ++i) {
        mpq_neg(t.c[i], t.c[i]);
    }
    conj_add(&j, &t, GE);
    qv_dot(&t, &ba, &ba);
    conj_add(&j, &t, GT);
    bool r = exists_t(j.c, j.n);
    qp_clear(&t);
    qv_clear(&pa);
    qv_clear(&ba);
    qv_clear(&pb);
    qv_clear(&x);
    conj_free(&j);
    return r;
}

bool oracle_vf(const double P[24])
{
    qv p, a, b, c;
    qv_init(&p);
    qv_init(&a);
    qv_init(&b);
    qv_init(&c);
    qv_point(&p, P, 0);
    qv_point(&a, P, 1);
    qv_point(&b, P, 2);
    qv_point(&c, P, 3);
    bool hit = point_point(&p, &a) || point_point(&p, &b) || point_point(&p, &c) || point_edge(&p, &a, &b) ||
               point_edge(&p, &b, &c) || point_edge(&p, &c, &a);
    if (!hit) {
        qv e1, e2, q, n, x, cb, pb;
        qv_init(&e1);
        qv_init(&e2);
        qv_init(&q);
        qv_init(&n);
        qv_init(&x);
        qv_init(&cb);
        qv_init(&pb);
        qv_sub(&e1, &b, &a);
        qv_sub(&e2, &c, &a);
        qv_sub(&q, &p, &a);
        qv_cross(&n, &e1, &e2);
        conj j;
        conj_init(&j);
        qp t;
        qp_init(&t);
        qv_dot(&t, &n, &q);
        conj_add(&j, &t, EQ);
        qv_dot(&t, &n, &n);
        conj_add(&j, &t, GT);
        qv_cross(&x, &e1, &q);
        qv_dot(&t, &x, &n);
        conj_add(&j, &t, GE);
        qv_cross(&x, &q, &e2);
        qv_dot(&t, &x, &n);
        conj_add(&j, &t, GE);
        qv_sub(&cb, &c, &b);
        qv_sub(&pb, &p, &b);
        qv_cross(&x, &cb, &pb);
        qv_dot(&t, &x, &n);
        conj_add(&j, &t, GE);
        hit = exists_t(j.c, j.n);
        qp_clear(&t);
        conj_free(&j);
        qv_clear(&e1);
        qv_clear(&e2);
        qv_clear(&q);
        qv_clear(&n);
        qv_clear(&x);
        qv_clear(&cb);
        qv_clear(&pb);
    }
    qv_clear(&p);
    qv_clear(&a);
    qv_clear(&b);
    qv_clear(&c);
    return hit;
}

bool oracle_ee(const double P[24])
{
    qv a0, a1, b0, b1;
    qv_init(&a0);
    qv_init(&a1);
    qv_init(&b0);
    qv_init(&b1);
    qv_point(&a0, P, 0);
    qv_point(&a1, P, 1);
    qv_point(&b0, P, 2);
    qv_point(&b1, P, 3);
    bool hit = point_point(&a0, &b0) || point_point(&a0, &b1) || point_point(&a1, &b0) || point_point(&a1, &b1) ||
               point_edge(&a0, &b0, &b1) || point_edge(&a1, &b0, &b1) || point_edge(&b0, &a0, &a1) ||
               point_edge(&b1, &a0, &a1);
    if (!hit) {
        qv ea, eb, r, m, x;
        qv_init(&ea);
        qv_init(&eb);
        qv_init(&r);
        qv_init(&m);
        qv_init(&x);
        qv_sub(&ea, &a1, &a0);
        qv_sub(&eb, &b1, &b0);
        qv_sub(&r, &b0, &a0);
        qv_cross(&m, &ea, &eb);
        conj j;
        conj_init(&j);
        qp t, M, S;
        qp_init(&t);
        qp_init(&M);
        qp_init(&S);
        qv_dot(&t, &r, &m);
        conj_add(&j, &t, EQ);
        qv_dot(&M, &m, &m);
        conj_add(&j, &M, GT);
        qv_cross(&x, &r, &eb);
        qv_dot(&S, &x, &m);
        conj_add(&j, &S, GE);
        qp_sub(&t, &M, &S);
        conj_add(&j, &t, GE);
        qv_cross(&x, &r, &ea);
        qv_dot(&S, &x, &m);
        conj_add(&j, &S, GE);
        qp_sub(&t, &M, &S);
        conj_add(&j, &t, GE);
        hit = exists_t(j.c, j.n);
        qp_clear(&t);
        qp_clear(&M);
        qp_clear(&S);
        conj_free(&j);
        qv_clear(&ea);
        qv_clear(&eb);
        qv_clear(&r);
        qv_clear(&m);
        qv_clear(&x);
    }
    qv_clear(&a0);
    qv_clear(&a1);
    qv_clear(&b0);
    qv_clear(&b1);
    return hit;
}
