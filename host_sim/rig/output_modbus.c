/* Output backend: coils on the Modbus I/O module that also serves the sensors
 * (a relay module on a real rig; leveler-plant-server in the tests).
 *
 * [outputs] watchdog_ms: written into the module's communication-watchdog
 * register at start, again whenever the link reconnects (a restarted module
 * forgets it), and read back then and once a second (a module restarted
 * behind an RTU line or a switch shows no reconnect): a value other than the
 * configured one is written again and read back before the outputs. A module
 * with one drives its outputs safe by itself when the rig stops writing
 * (crash, SIGKILL, hang, cable), the means real I/O modules offer; the main
 * loop re-sends the outputs well within that time. */
#define _POSIX_C_SOURCE 200809L
#include "output_backend.h"

#include <errno.h>
#include <modbus.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "modbus_link.h"

#define WATCHDOG_CHECK_NS 1000000000LL

typedef struct {
    rig_link *link;
    uint32_t watchdog_ms;          /* 0 = none */
    uint16_t watchdog_register;
    uint32_t armed_connects;       /* the link's connects count when last armed and read back */
    long long next_check_ns;
    unsigned long rearms;          /* writes after the first (a module that forgot it) */
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

static long long mono_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (long long)t.tv_sec * 1000000000LL + t.tv_nsec;
}

/* The module's watchdog register as configured, read back: 0, or -1 (message in err). */
static int arm_watchdog(modbus_outputs *m, char *err, size_t err_len)
{
    uint16_t now = 0;
    const char *what = "reading";
    modbus_t *ctx = rig_link_begin(m->link);
    bool ok = ctx != NULL && modbus_read_registers(ctx, m->watchdog_register, 1, &now) == 1;
    if (ctx != NULL)
        rig_link_end(m->link, ok);
    if (ok && now != m->watchdog_ms) {
        what = "writing";
        ok = (ctx = rig_link_begin(m->link)) != NULL && modbus_write_register(ctx, m->watchdog_register,
                                                                           (uint16_t)m->watchdog_ms) == 1;
        if (ctx != NULL)
            rig_link_end(m->link, ok);
        uint16_t back = 0;
        what = "reading back";
        ok = ok && (ctx = rig_link_begin(m->link)) != NULL &&
             modbus_read_registers(ctx, m->watchdog_register, 1, &back) == 1;
        if (ctx != NULL)
            rig_link_end(m->link, ok);
        if (ok && back != m->watchdog_ms) {
            snprintf(err, err_len, "modbus outputs: [outputs] watchdog_register %u: wrote %u ms, reads back %u",
                     m->watchdog_register, m->watchdog_ms, back);
            return -1;
        }
        if (ok && m->armed_connects != 0) {
            m->rearms++;
            fprintf(stderr, "leveler-rig: I/O module: watchdog register %u read %u: armed again (%u ms, read back)\n",
                    m->watchdog_register, now, m->watchdog_ms);
        }
    }
    if (!ok) {
        snprintf(err, err_len, "modbus outputs: [outputs] watchdog_register %u: %s the watchdog time: %s",
                 m->watchdog_register, what, ctx ? modbus_strerror(errno) : "module not connected");
        return -1;
    }
    m->armed_connects = rig_link_get_stats(m->link).connects;
    m->next_check_ns = mono_ns() + WATCHDOG_CHECK_NS;
    return 0;
}

/* Armed since the link's last connect and checked within the last second. */
static int keep_watchdog_armed(modbus_outputs *m, char *err, size_t err_len)
{
    if (m->watchdog_ms == 0 ||
        (m->armed_connects == rig_link_get_stats(m->link).connects && mono_ns() < m->next_check_ns))
        return 0;
    return arm_watchdog(m, err, err_len);
}

static int apply(void *impl, const bool on[HAL_OUT_COUNT], char *err, size_t err_len)
{
    modbus_outputs *m = impl;
    if (keep_watchdog_armed(m, err, err_len) != 0)
        return -1;
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
            snprintf(err, err_len, "modbus outputs: writing coil %u (%s): %s", m->coil[o], rig_config_output_names[o],
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
    m->watchdog_ms = 0;    /* nothing but the coils on the way out */
    apply(m, off, err, sizeof err);
    free(m);
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
    m->watchdog_ms = cfg->output_watchdog_ms;
    m->watchdog_register = cfg->output_watchdog_register;
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        m->configured[o] = cfg->pin[o].configured;
        m->coil[o] = cfg->pin[o].coil;
        if (o > 0 && o < HAL_OUT_STATUS_LED && m->coil[o] != m->coil[0] + o)
            m->contiguous = false;
    }
    out->impl = m;
    out->apply = apply;
    out->close = close_all;
    /* The watchdog armed and read back, then safe outputs (also after a
     * restart by systemd). A module slow to answer (a timeout of a few ms, a
     * busy machine) gets 1.5 s (one reconnect) before the rig gives up. */
    const bool off[HAL_OUT_COUNT] = {false};
    int rc = -1;
    for (int attempt = 0; attempt < 150 && rc != 0; attempt++) {
        if (attempt > 0) {
            struct timespec pause = {0, 10 * 1000000L};
            nanosleep(&pause, NULL);
        }
        rc = apply(m, off, err, err_len);
    }
    if (rc != 0)
        free(m);
    return rc;
}
