/* Output backend: coils on the Modbus module that also serves the sensors
 * (a relay module on a real rig; leveler-plant-server in the tests). */
#define _POSIX_C_SOURCE 200809L
#include "output_backend.h"

#include <errno.h>
#include <modbus.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    modbus_t *ctx;
    uint16_t coil[HAL_OUT_COUNT];
    bool configured[HAL_OUT_COUNT];
    bool contiguous; /* outputs 0..3 on consecutive coils: one FC 15 per tick */
} modbus_outputs;

static int apply(void *impl, const bool on[HAL_OUT_COUNT], char *err, size_t err_len)
{
    modbus_outputs *m = impl;
    if (m->contiguous) {
        uint8_t bits[HAL_OUT_STATUS_LED];
        for (int o = 0; o < HAL_OUT_STATUS_LED; o++)
            bits[o] = on[o] ? 1 : 0;
        if (modbus_write_bits(m->ctx, m->coil[0], HAL_OUT_STATUS_LED, bits) != HAL_OUT_STATUS_LED) {
            snprintf(err, err_len, "modbus outputs: writing coils %u..%u: %s", m->coil[0],
                     m->coil[0] + HAL_OUT_STATUS_LED - 1, modbus_strerror(errno));
            return -1;
        }
        if (m->configured[HAL_OUT_STATUS_LED])
            modbus_write_bit(m->ctx, m->coil[HAL_OUT_STATUS_LED], on[HAL_OUT_STATUS_LED]);
        return 0;
    }
    int rc = 0;
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        if (!m->configured[o])
            continue;
        if (modbus_write_bit(m->ctx, m->coil[o], on[o] ? 1 : 0) != 1 && rc == 0) {
            snprintf(err, err_len, "modbus outputs: writing coil %u (%s): %s", m->coil[o], rig_output_names[o],
                     modbus_strerror(errno));
            rc = -1;
        }
    }
    return rc;
}

static void close_all(void *impl)
{
    modbus_outputs *m = impl;
    const bool off[HAL_OUT_COUNT] = {false};
    char err[128];
    m->contiguous = false; /* coil by coil: one failure must not skip the others */
    apply(m, off, err, sizeof err);
    free(m);
}

int rig_modbus_outputs_open(const rig_config *cfg, modbus_t *ctx, rig_output_backend *out, char *err,
                            size_t err_len)
{
    modbus_outputs *m = calloc(1, sizeof *m);
    if (m == NULL) {
        snprintf(err, err_len, "modbus outputs: out of memory");
        return -1;
    }
    m->ctx = ctx;
    m->contiguous = true;
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        m->configured[o] = cfg->pin[o].configured;
        m->coil[o] = cfg->pin[o].coil;
        if (o > 0 && o < HAL_OUT_STATUS_LED && m->coil[o] != m->coil[0] + o)
            m->contiguous = false;
    }
    out->impl = m;
    out->apply = apply;
    out->close = close_all;
    const bool off[HAL_OUT_COUNT] = {false};
    if (apply(m, off, err, err_len) != 0) {
        free(m);
        return -1;
    }
    return 0;
}
