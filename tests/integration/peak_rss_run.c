/* peak_rss_run OUT PROGRAM [ARGS...]: runs PROGRAM, writes its peak resident set size in kB
 * (wait4's ru_maxrss) to the file OUT and exits with PROGRAM's status (128 + signal if killed).
 * A test's own process cannot measure this: Linux records the forking process's high-water RSS in the
 * child at exec (a pytest with NumPy loaded: 45 MB before the child runs a line), so the child is
 * started from this small process instead (about 1 MB). Used by test_peak_rss_bounds.py. */
#define _DEFAULT_SOURCE   /* wait4 */
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: peak_rss_run OUT PROGRAM [ARGS...]\n");
        return 2;
    }
    const pid_t pid = fork();
    if (pid < 0) {
        perror("peak_rss_run: fork");
        return 2;
    }
    if (pid == 0) {
        execvp(argv[2], argv + 2);
        perror("peak_rss_run: exec");
        _exit(127);
    }
    int status = 0;
    struct rusage ru;
    if (wait4(pid, &status, 0, &ru) != pid) {
        perror("peak_rss_run: wait4");
        return 2;
    }
    FILE *f = fopen(argv[1], "w");
    if (!f || fprintf(f, "%ld\n", ru.ru_maxrss) < 0 || fclose(f) != 0) {
        perror("peak_rss_run: writing the result");
        return 2;
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}
