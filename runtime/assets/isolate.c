/* A parser in a child process. See isolate.h. */
#define _POSIX_C_SOURCE 200809L

#include "isolate.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#if defined(__unix__) || defined(__APPLE__)
#define WEFT_HAVE_FORK 1
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#else
#define WEFT_HAVE_FORK 0
#endif

#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(memory_sanitizer) || __has_feature(thread_sanitizer)
#define WEFT_SANITIZED 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define WEFT_SANITIZED 1
#endif
#ifndef WEFT_SANITIZED
#define WEFT_SANITIZED 0
#endif

/* Sanitizer runtimes (and libFuzzer through them) run a death callback when they report an
 * error; libFuzzer's saves the current input as a crash of the whole run. The child clears it:
 * what happens in the child is reported to the parent by its exit status instead. */
extern void __sanitizer_set_death_callback(void (*callback)(void)) __attribute__((weak));

bool weft__isolation_available(void)
{
    return WEFT_HAVE_FORK != 0;
}

bool weft__write_all(int fd, const void *data, size_t n)
{
#if WEFT_HAVE_FORK
    const uint8_t *p = data;
    while (n > 0) {
        ssize_t w = write(fd, p, n);
        if (w < 0 && errno == EINTR) {
            continue;
        }
        if (w <= 0) {
            return false;
        }
        p += w;
        n -= (size_t)w;
    }
    return true;
#else
    (void)fd, (void)data;
    return n == 0;
#endif
}

#if WEFT_HAVE_FORK
static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void child_setup(const weft__isolated_limits *limits)
{
    if (__sanitizer_set_death_callback) {
        __sanitizer_set_death_callback(NULL);
    }
    /* a fault ends the child with its signal, not the parent's (or a fuzzer's) handlers */
    static const int faults[] = {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT, SIGTRAP, SIGSYS, SIGALRM, SIGPIPE};
    struct sigaction dfl;
    memset(&dfl, 0, sizeof dfl);
    dfl.sa_handler = SIG_DFL;
    sigemptyset(&dfl.sa_mask);
    for (size_t i = 0; i < sizeof faults / sizeof faults[0]; ++i) {
        sigaction(faults[i], &dfl, NULL);
    }
    sigset_t none;
    sigemptyset(&none);
    sigprocmask(SIG_SETMASK, &none, NULL);
    struct rlimit no_core = {0, 0};
    setrlimit(RLIMIT_CORE, &no_core);
    if (limits->address_space_bytes > 0 && !WEFT_SANITIZED) {
        struct rlimit as = {(rlim_t)limits->address_space_bytes, (rlim_t)limits->address_space_bytes};
        setrlimit(RLIMIT_AS, &as);
    }
}

/* Reads until EOF, the deadline or max_bytes; returns the end (EXITED meaning "EOF seen"). */
static weft__isolated_end read_child(int fd, double deadline, size_t max_bytes, weft__isolated_run *out)
{
    size_t cap = 0;
    for (;;) {
        double left = deadline - now_seconds();
        if (left <= 0) {
            return WEFT__ISOLATED_TIMED_OUT;
        }
        struct pollfd p = {fd, POLLIN, 0};
        int ms = left > 1e6 ? 1000000000 : (int)(left * 1000.0) + 1;
        int n = poll(&p, 1, ms);
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n < 0) {
            out->code = errno;
            return WEFT__ISOLATED_NO_CHILD;
        }
        if (n == 0) {
            continue; /* the deadline check above ends the wait */
        }
        if (out->size == cap) {
            if (cap >= max_bytes) {
                return WEFT__ISOLATED_TOO_LARGE;
            }
            size_t next = cap ? cap * 2 : 65536;
            next = next > max_bytes ? max_bytes : next;
            uint8_t *grown = realloc(out->bytes, next);
            if (!grown) {
                out->code = ENOMEM;
                return WEFT__ISOLATED_NO_CHILD;
            }
            out->bytes = grown;
            cap = next;
        }
        ssize_t r = read(fd, out->bytes + out->size, cap - out->size);
        if (r < 0 && (errno == EINTR || errno == EAGAIN)) {
            continue;
        }
        if (r < 0) {
            out->code = errno;
            return WEFT__ISOLATED_NO_CHILD;
        }
        if (r == 0) {
            return WEFT__ISOLATED_EXITED;
        }
        out->size += (size_t)r;
    }
}
#endif

void weft__run_isolated(weft__isolated_fn fn, void *arg, const weft__isolated_limits *limits, weft__isolated_run *out)
{
    memset(out, 0, sizeof *out);
#if WEFT_HAVE_FORK
    int fds[2];
    if (pipe(fds) != 0) {
        out->end = WEFT__ISOLATED_NO_CHILD;
        out->code = errno;
        return;
    }
    const double deadline = now_seconds() + limits->seconds;
    pid_t pid = fork();
    if (pid < 0) {
        out->end = WEFT__ISOLATED_NO_CHILD;
        out->code = errno;
        close(fds[0]);
        close(fds[1]);
        return;
    }
    if (pid == 0) {
        close(fds[0]);
        child_setup(limits);
        fn(arg, fds[1]);
        _exit(0);
    }
    close(fds[1]);
    weft__isolated_end read_end = read_child(fds[0], deadline, limits->max_bytes, out);
    close(fds[0]);
    if (read_end != WEFT__ISOLATED_EXITED) {
        kill(pid, SIGKILL);
    }
    int status = 0;
    pid_t w;
    do {
        w = waitpid(pid, &status, 0);
    } while (w < 0 && errno == EINTR);
    if (read_end != WEFT__ISOLATED_EXITED) {
        out->end = read_end;
        return;
    }
    if (w < 0) {
        /* SIGCHLD ignored by the host: the child was reaped for us; its output tells the rest */
        out->end = WEFT__ISOLATED_EXITED;
    } else if (WIFSIGNALED(status)) {
        out->end = WEFT__ISOLATED_SIGNALLED;
        out->code = WTERMSIG(status);
    } else if (WIFEXITED(status) && WEXITSTATUS(status) != 0) {
        out->end = WEFT__ISOLATED_FAILED;
        out->code = WEXITSTATUS(status);
    } else {
        out->end = WEFT__ISOLATED_EXITED;
    }
#else
    (void)fn, (void)arg, (void)limits;
    out->end = WEFT__ISOLATED_NO_CHILD;
    out->code = ENOSYS;
#endif
}
