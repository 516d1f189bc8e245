/* Output backend: coils on the Modbus I/O module that also serves the sensors
 * (a relay module on a real rig; leveler-plant-server in the tests).
 *
 * [outputs] watchdog_ms: written once at start into the module's
 * communication-watchdog register. A module with one drives its outputs safe
 * by itself when the rig stops writing (crash, SIGKILL, hang, cable), the
 * means real I/O modules offer; the main loop re-sends the outputs well
 * within that time (rig_modbus_outputs_refresh_ms). */
#define _POSIX_C_SOURCE 200809L
#include "output_backend.h"

#include <errno.h>
#include <modbus.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "modbus_link.h"

typedef struct {
    rig_link *link;
    uint16_t coil[HAL_OUT_COUNT];
    bool configured[HAL_OUT_COUNT];
    bool contiguous; /* outputs 0..3 on consecutive coils: one FC 15 per tick */
} modbus_outputs;

static int write_contiguous(modbus_outputs *m, modbus_t *ctx, const bool on[HAL_OUT_COUNT], char *err,
                            size_t err_len)
{
    uint8_t bits[HAL_OUT_STATUS_LED];
    for (int o = 0; o < HAL_OUT_STATUS_LED; o++)
        bits[o] = on[o] ? 1 : 0;
    bool ok = modbus_write_bits(ctx, m->coil[0], HAL_OUT_STATUS_LED, bits) == HAL_OUT_STATUS_LED;
    if (!ok)
        snprintf(err, err_len, "modbus outputs: writing coils %u..%u: %s", m->coil[0],
                 m->coil[0] + HAL_OUT_STATUS_LED - 1, modbus_strerror(errno));
    rig_link_end(m->link, ok);
    if (ok && m->configured[HAL_OUT_STATUS_LED] && (ctx = rig_link_begin(m->link)) != NULL)
        rig_link_end(m->link, modbus_write_bit(ctx, m->coil[HAL_OUT_STATUS_LED], on[HAL_OUT_STATUS_LED]) == 1);
    return ok ? 0 : -1;
}

static int apply(void *impl, const bool on[HAL_OUT_COUNT], char *err, size_t err_len)
{
    modbus_outputs *m = impl;
    modbus_t *ctx = rig_link_begin(m->link);
    if (ctx == NULL) {
        snprintf(err, err_len, "modbus outputs: module not connected");
        return -1;
    }
    if (m->contiguous)
        return write_contiguous(m, ctx, on, err, err_len);
    int rc = 0;
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        if (!m->configured[o] || (ctx = rig_link_begin(m->link)) == NULL)
            continue;
        bool ok = modbus_write_bit(ctx, m->coil[o], on[o] ? 1 : 0) == 1;
        if (!ok && rc == 0) {
            snprintf(err, err_len, "modbus outputs: writing coil %u (%s): %s", m->coil[o], rig_output_names[o],
                     modbus_strerror(errno));
            rc = -1;
        }
        rig_link_end(m->link, ok);
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

static int write_watchdog(const rig_config *cfg, rig_link *link, char *err, size_t err_len)
{
    modbus_t *ctx = rig_link_begin(link);
    bool ok = ctx != NULL &&
              modbus_write_register(ctx, (int)cfg->output_watchdog_register, (uint16_t)cfg->output_watchdog_ms) == 1;
    if (ctx != NULL)
        rig_link_end(link, ok);
    if (!ok)
        snprintf(err, err_len, "modbus outputs: [outputs] watchdog_register %u: cannot write the watchdog time: %s",
                 cfg->output_watchdog_register, ctx ? modbus_strerror(errno) : "module not connected");
    return ok ? 0 : -1;
}

int rig_modbus_outputs_open(const rig_config *cfg, rig_link *link, rig_output_backend *out, char *err,
                            size_t err_len)
{
    modbus_outputs *m = calloc(1, sizeof *m);
    if (m == NULL) {
        snprintf(err, err_len, "modbus outputs: out of memory");
        return -1;
    }
    m->link = link;
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
    /* Safe outputs first (also after a restart by systemd), then arm the
     * watchdog. A module slow to answer (a timeout of a few ms, a busy
     * machine) gets 1.5 s (one reconnect) before the rig gives up. */
    const bool off[HAL_OUT_COUNT] = {false};
    int rc = -1;
    for (int attempt = 0; attempt < 150 && rc != 0; attempt++) {
        if (attempt > 0) {
            struct timespec pause = {0, 10 * 1000000L};
            nanosleep(&pause, NULL);
        }
        rc = apply(m, off, err, err_len);
        if (rc == 0 && cfg->output_watchdog_ms > 0)
            rc = write_watchdog(cfg, link, err, err_len);
    }
    if (rc != 0)
        free(m);
    return rc;
}
