/* Running the `weft` binary from a test: one child process, stdout into a file or inherited. */
#ifndef WEFT_TESTS_TOOL_RUN_H
#define WEFT_TESTS_TOOL_RUN_H

#include <fcntl.h>
#include <stdio.h>
#include <spawn.h>
#include <sys/wait.h>

extern char **environ;

/* Runs argv (argv[0] a path, NULL-terminated) with stdout into out_path (NULL: inherited);
 * returns the exit status, or -1 when it could not start or did not exit. */
/* As tool_run, with standard error into err_path too (NULL: inherited). */
static inline int tool_run_err(const char *const argv[], const char *out_path, const char *err_path)
{
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    if (out_path) {
        posix_spawn_file_actions_addopen(&fa, 1, out_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    }
    if (err_path) {
        posix_spawn_file_actions_addopen(&fa, 2, err_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    }
    pid_t pid;
    int ok = posix_spawn(&pid, argv[0], &fa, NULL, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (ok != 0) {
        return -1;
    }
    int status = 0;
    if (waitpid(pid, &status, 0) < 0) {
        return -1;
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static inline int tool_run(const char *const argv[], const char *out_path)
{
    return tool_run_err(argv, out_path, NULL);
}

/* The text of the file at path (at most cap - 1 bytes); empty when it cannot be read. */
static inline void tool_slurp(const char *path, char *buf, size_t cap)
{
    buf[0] = '\0';
    FILE *f = fopen(path, "rb");
    if (f) {
        size_t n = fread(buf, 1, cap - 1, f);
        buf[n] = '\0';
        fclose(f);
    }
}

#endif
