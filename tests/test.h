/* Minimal test harness: CHECK* macros count failures; TEST_MAIN runs the listed cases and
 * prints "N passed, N failed" per executable. ctest sees the exit status. */
#ifndef WEFT_TEST_H
#define WEFT_TEST_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int test_failures_;
static int test_checks_;

#define CHECK(cond)                                                                        \
    do {                                                                                   \
        test_checks_++;                                                                    \
        if (!(cond)) {                                                                     \
            test_failures_++;                                                              \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);       \
        }                                                                                  \
    } while (0)

#define CHECK_MSG(cond, ...)                                                               \
    do {                                                                                   \
        test_checks_++;                                                                    \
        if (!(cond)) {                                                                     \
            test_failures_++;                                                              \
            fprintf(stderr, "%s:%d: CHECK failed: %s: ", __FILE__, __LINE__, #cond);       \
            fprintf(stderr, __VA_ARGS__);                                                  \
            fputc('\n', stderr);                                                           \
        }                                                                                  \
    } while (0)

#define CHECK_EQ_INT(a, b)                                                                 \
    do {                                                                                   \
        long long va_ = (long long)(a), vb_ = (long long)(b);                              \
        CHECK_MSG(va_ == vb_, "%s = %lld, %s = %lld", #a, va_, #b, vb_);                   \
    } while (0)

/* |a - b| <= tol */
#define CHECK_NEAR(a, b, tol)                                                              \
    do {                                                                                   \
        double va_ = (double)(a), vb_ = (double)(b);                                       \
        CHECK_MSG(fabs(va_ - vb_) <= (tol), "%s = %.9g, %s = %.9g, tol %.3g", #a, va_, #b, \
                  vb_, (double)(tol));                                                     \
    } while (0)

#define CHECK_RESULT(expr, expected)                                                       \
    do {                                                                                   \
        weft_result r_ = (expr);                                                           \
        CHECK_MSG(r_ == (expected), "%s returned %s (%s), expected %s", #expr,             \
                  weft_result_string(r_), weft_last_error(), weft_result_string(expected)); \
    } while (0)

typedef struct test_case_ {
    const char *name;
    void (*fn)(void);
} test_case_;

#define TEST_CASE(fn) {#fn, fn}

static inline int test_run_(const test_case_ *cases, size_t n, int argc, char **argv)
{
    int passed = 0, failed = 0;
    for (size_t i = 0; i < n; ++i) {
        if (argc > 1 && !strstr(cases[i].name, argv[1])) {
            continue;
        }
        int before = test_failures_;
        cases[i].fn();
        if (test_failures_ == before) {
            passed++;
        } else {
            failed++;
            fprintf(stderr, "FAILED: %s\n", cases[i].name);
        }
    }
    printf("%d passed, %d failed (%d checks)\n", passed, failed, test_checks_);
    return failed == 0 && test_checks_ > 0 ? 0 : 1;
}

#define TEST_MAIN(...)                                                                     \
    int main(int argc, char **argv)                                                        \
    {                                                                                      \
        static const test_case_ cases_[] = {__VA_ARGS__};                                  \
        return test_run_(cases_, sizeof cases_ / sizeof cases_[0], argc, argv);           \
    }

/* Deterministic xorshift generator for test data. */
typedef struct test_rng {
    unsigned long long s;
} test_rng;

static inline unsigned test_rng_u32(test_rng *r)
{
    r->s ^= r->s << 13;
    r->s ^= r->s >> 7;
    r->s ^= r->s << 17;
    return (unsigned)(r->s >> 11);
}

/* Uniform in [lo, hi). */
static inline float test_rng_float(test_rng *r, float lo, float hi)
{
    return lo + (hi - lo) * (float)(test_rng_u32(r) & 0xffffff) / 16777216.0f;
}

#endif
