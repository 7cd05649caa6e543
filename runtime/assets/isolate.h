/*
 * Running a third-party parser in a child process (weft_assets, internal).
 *
 * assimp reads users' glTF and FBX files; it is uninstrumented C++ that weft cannot fix, and
 * malformed files make it read address 0, abort on assertions, hang or ask for hundreds of
 * gigabytes. weft__run_isolated forks, runs `fn` in the child with a bounded address space and
 * no core dump, and returns the bytes `fn` wrote to its descriptor, with how the child ended. The
 * caller decodes and re-validates those bytes as untrusted input: a crash, a hang or garbage in
 * the child becomes an error for one file, never a crash of the caller.
 *
 * POSIX only (fork, pipe, poll); elsewhere weft__isolation_available() is false and callers run
 * the parser in-process. Call from a single-threaded part of the program or accept fork's usual
 * rule: the child runs only `fn`, so other threads' locks held at fork time must not be needed
 * by it (glibc's malloc is safe across fork).
 */
#ifndef WEFT_ASSETS_ISOLATE_H
#define WEFT_ASSETS_ISOLATE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef enum weft__isolated_end {
    WEFT__ISOLATED_EXITED,    /* the child returned from fn and exited (code 0) */
    WEFT__ISOLATED_FAILED,    /* the child exited with a non-zero code (code: the exit status) */
    WEFT__ISOLATED_SIGNALLED, /* the child was killed by a signal (code: the signal) */
    WEFT__ISOLATED_TIMED_OUT, /* the child ran past the time limit and was killed */
    WEFT__ISOLATED_TOO_LARGE, /* the child wrote more than max_bytes and was killed */
    WEFT__ISOLATED_NO_CHILD,  /* fork, pipe or poll failed (code: errno); nothing ran */
} weft__isolated_end;

typedef struct weft__isolated_run {
    uint8_t *bytes; /* what fn wrote (malloc'd, free it; NULL when nothing was written) */
    size_t size;
    weft__isolated_end end;
    int code;
} weft__isolated_run;

typedef struct weft__isolated_limits {
    double seconds;                /* wall-clock limit of the child (> 0) */
    uint64_t address_space_bytes;  /* the child's RLIMIT_AS; 0: unlimited (sanitizer builds ignore it) */
    size_t max_bytes;              /* largest output accepted */
} weft__isolated_limits;

typedef void (*weft__isolated_fn)(void *arg, int fd);

bool weft__isolation_available(void);

/* Runs fn(arg, fd) in a child process; fills *out (always: free out->bytes afterwards). */
void weft__run_isolated(weft__isolated_fn fn, void *arg, const weft__isolated_limits *limits, weft__isolated_run *out);

/* Writes all n bytes to fd (retrying short writes); false on error. For use inside fn. */
bool weft__write_all(int fd, const void *data, size_t n);

#endif
