/* The engine handle's fields, for the engine's own files (engine*.c) only. */
#ifndef LEVELER_ENGINE_INTERNAL_H
#define LEVELER_ENGINE_INTERNAL_H

#include <stdbool.h>

#include "effects.h"
#include "leveler/hal.h"
#include "plant.h"
#include "stepper.h"

struct engine {
    plant_config cfg;  /* read once by engine_open */
    char name[256];    /* the config's path, for messages */
    plant_fx run_fx;   /* the plant of the run in progress (engine_run) */
    /* the stepping API's run (engine_step.c) */
    plant_fx step_fx;
    plant_rng step_rng;
    sim_load_step step_rows[4];
    sim_schedule_cursor step_cursor;
    sim_stepper stepper;
    double step_end_s;
    bool step_outputs[HAL_OUT_COUNT]; /* what the emulated image drives */
};

#endif /* LEVELER_ENGINE_INTERNAL_H */
