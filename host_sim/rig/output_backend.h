/*
 * Where leveler-rig's outputs go. One small interface, several backends:
 *   gpio_gpiod_v1.c / gpio_gpiod_v2.c  libgpiod lines (exactly one is compiled,
 *                                      chosen by the libgpiod version at configure time)
 *   output_modbus.c                    coils on the Modbus analog module (tests, or
 *                                      a relay module)
 * apply() takes every output's wanted state at once (true = energised) and
 * must be safe to call from the shutdown path.
 */
#ifndef LEVELER_RIG_OUTPUT_BACKEND_H
#define LEVELER_RIG_OUTPUT_BACKEND_H

#include <stdbool.h>
#include <stddef.h>

#include "leveler/hal.h"
#include "rig_config.h"

typedef struct rig_output_backend {
    void *impl;
    /* 0 on success, -1 with a message in err. */
    int (*apply)(void *impl, const bool on[HAL_OUT_COUNT], char *err, size_t err_len);
    /* Drives every line to the safe (de-energised) state, then releases it. */
    void (*close)(void *impl);
} rig_output_backend;

/* libgpiod: requests every configured line as an output, already de-energised. */
int rig_gpiod_open(const rig_config *cfg, rig_output_backend *out, char *err, size_t err_len);

struct rig_link;
/* Coils over the module link (not owned); writes all coils off first, then
 * the module's communication watchdog time when [outputs] watchdog_ms is set. */
int rig_modbus_outputs_open(const rig_config *cfg, struct rig_link *link, rig_output_backend *out, char *err,
                            size_t err_len);

#endif
