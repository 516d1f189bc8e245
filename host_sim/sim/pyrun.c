/* Running a module of the Python package (pyrun.h). */
#define _POSIX_C_SOURCE 200809L
#include "pyrun.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#ifndef LEVELER_SOURCE_DIR
#define LEVELER_SOURCE_DIR "."
#endif
#ifndef LEVELER_DEFAULT_PYTHON
#define LEVELER_DEFAULT_PYTHON "python3"
#endif

const char *sim_python_path(void)
{
    const char *py = getenv("LEVELER_PYTHON");
    return (py && *py) ? py : LEVELER_DEFAULT_PYTHON;
}

const char *sim_python_scripts_dir(void)
{
    static char buf[1024];
    const char *scripts = getenv("LEVELER_SCRIPTS_DIR");
    if (scripts && *scripts)
        return scripts;
    snprintf(buf, sizeof buf, "%s/scripts", LEVELER_SOURCE_DIR);
    return buf;
}

/* leveler-sim beside this program (it is this program for leveler-sim), so the
 * Python package asks the same build's C loader for configs (LEVELER_SIM). */
static void export_leveler_sim(void)
{
    char self[4096];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0)
        return;
    self[n] = 0;
    char *slash = strrchr(self, '/');
    if (!slash || (size_t)(slash - self) + sizeof "/leveler-sim" > sizeof self)
        return;
    strcpy(slash, "/leveler-sim");
    if (access(self, X_OK) == 0)
        setenv("LEVELER_SIM", self, 0);
}

int sim_python_module(const char *tool, const char *module, const char *const *args)
{
    const char *py = sim_python_path();
    const char *scripts = sim_python_scripts_dir();
    char file[1200], dotted[128];
    struct stat st;
    snprintf(file, sizeof file, "%s/leveler/%s.py", scripts, module);
    if (stat(file, &st) != 0)
        return -2;
    snprintf(dotted, sizeof dotted, "leveler.%s", module);
    const char *argv[40];
    int n = 0;
    argv[n++] = py;
    argv[n++] = "-m";
    argv[n++] = dotted;
    for (int i = 0; args && args[i] && n < 39; i++)
        argv[n++] = args[i];
    argv[n] = NULL;
    fflush(stdout);
    pid_t pid = fork();
    if (pid < 0) {
        fprintf(stderr, "%s: fork: %s\n", tool, strerror(errno));
        return 1;
    }
    if (pid == 0) {
        setenv("PYTHONPATH", scripts, 1);
        export_leveler_sim();
        execvp(py, (char *const *)argv);
        fprintf(stderr, "%s: cannot run %s: %s (set LEVELER_PYTHON)\n", tool, py, strerror(errno));
        _exit(127);
    }
    int status;
    while (waitpid(pid, &status, 0) < 0)
        if (errno != EINTR)
            return 1;
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        fprintf(stderr, "%s: %s failed (status %d)\n", tool, dotted, WIFEXITED(status) ? WEXITSTATUS(status) : -1);
        return 1;
    }
    return 0;
}
