/* A request's schedule rows (register writes, loads) as the simulator's
 * sim_load_step rows, for engine_run.c and engine_schedule.c. */
#ifndef LEVELER_ENGINE_WRITES_H
#define LEVELER_ENGINE_WRITES_H

#include <stdint.h>

#include "stepper.h"

/* The most rows a request may carry. */
#define ENGINE_MAX_WRITE_ROWS 1024

/* n rows at t_s[i] (strictly increasing) into *rows (malloc'ed, the caller
 * frees; NULL for n = 0): the load load_n[i] (load_n may be NULL: writes
 * only) and values[i * SIM_SCHEDULE_REG_COUNT + j] for sim_schedule_regs[j],
 * -1 = no write. 0, or -1 with err. */
int engine_writes_take(int n, const double *t_s, const double *load_n, const int32_t *values, sim_load_step **rows,
                       char *err, int err_len);

#endif /* LEVELER_ENGINE_WRITES_H */
