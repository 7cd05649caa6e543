/* The child-process runner behind the glTF/FBX import (runtime/assets/isolate.c): output
 * returned whole, and every way a child can end (exit code, signal, hang, flood) reported as
 * such without harming the caller. */
#define _POSIX_C_SOURCE 200809L

#include "test.h"
#include "isolate.h"

#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static const weft__isolated_limits k_limits = {10.0, 0, (size_t)1 << 24};

static void write_pattern(void *arg, int fd)
{
    size_t n = *(const size_t *)arg;
    uint8_t buf[4096];
    for (size_t done = 0; done < n;) {
        size_t k = n - done < sizeof buf ? n - done : sizeof buf;
        for (size_t i = 0; i < k; ++i) {
            buf[i] = (uint8_t)((done + i) * 31u);
        }
        if (!weft__write_all(fd, buf, k)) {
            _exit(3);
        }
        done += k;
    }
}

static void test_output(void)
{
    CHECK(weft__isolation_available());
    /* more than a pipe's buffer, so the parent must read while the child writes */
    static const size_t sizes[] = {0, 1, 65536, 3000001};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; ++s) {
        size_t n = sizes[s];
        weft__isolated_run run;
        weft__run_isolated(write_pattern, &n, &k_limits, &run);
        CHECK_EQ_INT(run.end, WEFT__ISOLATED_EXITED);
        CHECK_MSG(run.size == n, "%zu bytes for %zu", run.size, n);
        bool same = run.size == n;
        for (size_t i = 0; same && i < n; ++i) {
            same = run.bytes[i] == (uint8_t)(i * 31u);
        }
        CHECK(same);
        free(run.bytes);
    }
}

static void crash(void *arg, int fd)
{
    weft__write_all(fd, "A", 1);
    if (*(const int *)arg == 0) {
        volatile int *null_pointer = NULL;
        *null_pointer = 1; /* read/write address 0 as assimp does */
    } else if (*(const int *)arg == 1) {
        abort();
    } else {
        _exit(7);
    }
}

static void test_child_ends(void)
{
    for (int how = 0; how < 3; ++how) {
        weft__isolated_run run;
        weft__run_isolated(crash, &how, &k_limits, &run);
        CHECK_MSG(run.size == 1 && run.bytes && run.bytes[0] == 'A', "case %d: %zu bytes", how, run.size);
        if (how == 0) {
            CHECK_EQ_INT(run.end, WEFT__ISOLATED_SIGNALLED);
            CHECK_MSG(run.code == SIGSEGV || run.code == SIGBUS, "signal %d", run.code);
        } else if (how == 1) {
            CHECK_EQ_INT(run.end, WEFT__ISOLATED_SIGNALLED);
            CHECK_EQ_INT(run.code, SIGABRT);
        } else {
            CHECK_EQ_INT(run.end, WEFT__ISOLATED_FAILED);
            CHECK_EQ_INT(run.code, 7);
        }
        free(run.bytes);
    }
}

static void hang(void *arg, int fd)
{
    (void)arg;
    weft__write_all(fd, "A", 1);
    for (;;) {
        pause();
    }
}

static void flood(void *arg, int fd)
{
    (void)arg;
    uint8_t buf[4096] = {0};
    while (weft__write_all(fd, buf, sizeof buf)) {
    }
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void test_limits(void)
{
    weft__isolated_limits short_time = {0.3, 0, 1024};
    weft__isolated_run run;
    double t0 = now();
    weft__run_isolated(hang, NULL, &short_time, &run);
    double took = now() - t0;
    CHECK_EQ_INT(run.end, WEFT__ISOLATED_TIMED_OUT);
    CHECK_MSG(took >= 0.29 && took < 5.0, "a 0.3 s limit took %.2f s", took);
    CHECK(run.size == 1);
    free(run.bytes);

    weft__isolated_limits small = {10.0, 0, 100000};
    weft__run_isolated(flood, NULL, &small, &run);
    CHECK_EQ_INT(run.end, WEFT__ISOLATED_TOO_LARGE);
    CHECK(run.size == 100000);
    free(run.bytes);
}

TEST_MAIN(TEST_CASE(test_output), TEST_CASE(test_child_ends), TEST_CASE(test_limits))
