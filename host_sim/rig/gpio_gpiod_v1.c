/* Output backend over libgpiod 1.x (Debian 12 ships 1.6). Active-low is
 * handled by the library's request flag, so on = logical "energised". */
#define _POSIX_C_SOURCE 200809L
#include "output_backend.h"

#include <errno.h>
#include <gpiod.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    struct gpiod_chip *chip[HAL_OUT_COUNT]; /* one handle per output: simple, chips may differ */
    struct gpiod_line *line[HAL_OUT_COUNT];
} gpiod_v1;

static int apply(void *impl, const bool on[HAL_OUT_COUNT], char *err, size_t err_len)
{
    gpiod_v1 *g = impl;
    int rc = 0;
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        if (g->line[o] == NULL)
            continue;
        if (gpiod_line_set_value(g->line[o], on[o] ? 1 : 0) != 0 && rc == 0) {
            snprintf(err, err_len, "gpiod: setting output %s: %s", rig_config_output_names[o], strerror(errno));
            rc = -1; /* keep going: the other outputs must still follow */
        }
    }
    return rc;
}

static void close_all(void *impl)
{
    gpiod_v1 *g = impl;
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        if (g->line[o] != NULL) {
            gpiod_line_set_value(g->line[o], 0);
            gpiod_line_release(g->line[o]);
        }
        if (g->chip[o] != NULL)
            gpiod_chip_close(g->chip[o]);
    }
    free(g);
}

int rig_gpiod_open(const rig_config *cfg, rig_output_backend *out, char *err, size_t err_len)
{
    gpiod_v1 *g = calloc(1, sizeof *g);
    if (g == NULL) {
        snprintf(err, err_len, "gpiod: out of memory");
        return -1;
    }
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        const rig_output_pin *pin = &cfg->pin[o];
        if (!pin->configured)
            continue;
        g->chip[o] = gpiod_chip_open_lookup(pin->chip);
        if (g->chip[o] == NULL) {
            snprintf(err, err_len, "gpiod: [output.%s] chip: cannot open '%s': %s", rig_config_output_names[o], pin->chip,
                     strerror(errno));
            goto fail;
        }
        g->line[o] = gpiod_chip_get_line(g->chip[o], (unsigned)pin->line);
        if (g->line[o] == NULL) {
            snprintf(err, err_len, "gpiod: [output.%s] line: no line %u on '%s': %s", rig_config_output_names[o],
                     (unsigned)pin->line, pin->chip, strerror(errno));
            goto fail;
        }
        int flags = pin->active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
        /* default value 0 = de-energised from the very first instant */
        if (gpiod_line_request_output_flags(g->line[o], cfg->consumer, flags, 0) != 0) {
            snprintf(err, err_len, "gpiod: [output.%s] line: cannot request line %u on '%s': %s",
                     rig_config_output_names[o], (unsigned)pin->line, pin->chip, strerror(errno));
            g->line[o] = NULL; /* not ours to release */
            goto fail;
        }
    }
    out->impl = g;
    out->apply = apply;
    out->close = close_all;
    return 0;
fail:
    close_all(g);
    return -1;
}
