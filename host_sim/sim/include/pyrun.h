/*
 * Run a module of the project's Python package (scripts/leveler) from a host
 * tool: $LEVELER_PYTHON (else the build's .venv python) -m leveler.<module>
 * args..., with PYTHONPATH = $LEVELER_SCRIPTS_DIR (else <source>/scripts) and
 * LEVELER_SIM = the leveler-sim beside the tool unless set (leveler.config
 * asks it for configs).
 */
#ifndef LEVELER_SIM_PYRUN_H
#define LEVELER_SIM_PYRUN_H

/* tool names the caller in messages; args is NULL-terminated (at most 32).
 * 0 on exit status 0; 1 otherwise (the reason printed on stderr); -2 when the
 * module file is not there (nothing printed: the caller says what to do). */
int sim_python_module(const char *tool, const char *module, const char *const *args);

/* The python and scripts folder sim_python_module() would use. */
const char *sim_python_path(void);
const char *sim_python_scripts_dir(void);

#endif /* LEVELER_SIM_PYRUN_H */
