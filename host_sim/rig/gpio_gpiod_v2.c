/* Output backend over libgpiod 2.x. Active-low is a line setting, so
 * on = logical "energised". Each output gets its own request (chips may differ). */
#define _POSIX_C_SOURCE 200809L
#include "output_backend.h"

#include <errno.h>
#include <gpiod.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    struct gpiod_line_request *request[HAL_OUT_COUNT];
    unsigned int offset[HAL_OUT_COUNT];
} gpiod_v2;

static int apply(void *impl, const bool on[HAL_OUT_COUNT], char *err, size_t err_len)
{
    gpiod_v2 *g = impl;
    int rc = 0;
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        if (g->request[o] == NULL)
            continue;
        enum gpiod_line_value v = on[o] ? GPIOD_LINE_VALUE_ACTIVE : GPIOD_LINE_VALUE_INACTIVE;
        if (gpiod_line_request_set_value(g->request[o], g->offset[o], v) != 0 && rc == 0) {
            snprintf(err, err_len, "gpiod: setting output %s: %s", rig_config_output_names[o], strerror(errno));
            rc = -1;
        }
    }
    return rc;
}

static void close_all(void *impl)
{
    gpiod_v2 *g = impl;
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        if (g->request[o] != NULL) {
            gpiod_line_request_set_value(g->request[o], g->offset[o], GPIOD_LINE_VALUE_INACTIVE);
            gpiod_line_request_release(g->request[o]);
        }
    }
    free(g);
}

/* chip may be a path, "gpiochipN" or a bare number. */
static void chip_path(const char *chip, char *buf, size_t cap)
{
    if (chip[0] == '/')
        snprintf(buf, cap, "%s", chip);
    else if (chip[0] >= '0' && chip[0] <= '9')
        snprintf(buf, cap, "/dev/gpiochip%s", chip);
    else
        snprintf(buf, cap, "/dev/%s", chip);
}

static struct gpiod_line_request *request_one(const rig_config *cfg, const rig_output_pin *pin)
{
    char path[RIG_TEXT_MAX + 16];
    chip_path(pin->chip, path, sizeof path);
    struct gpiod_chip *chip = gpiod_chip_open(path);
    if (chip == NULL)
        return NULL;
    struct gpiod_line_settings *settings = gpiod_line_settings_new();
    struct gpiod_line_config *line_cfg = gpiod_line_config_new();
    struct gpiod_request_config *req_cfg = gpiod_request_config_new();
    struct gpiod_line_request *request = NULL;
    unsigned int offset = (unsigned int)pin->line;
    if (settings && line_cfg && req_cfg &&
        gpiod_line_settings_set_direction(settings, GPIOD_LINE_DIRECTION_OUTPUT) == 0 &&
        gpiod_line_settings_set_output_value(settings, GPIOD_LINE_VALUE_INACTIVE) == 0) {
        gpiod_line_settings_set_active_low(settings, pin->active_low);
        gpiod_request_config_set_consumer(req_cfg, cfg->consumer);
        if (gpiod_line_config_add_line_settings(line_cfg, &offset, 1, settings) == 0)
            request = gpiod_chip_request_lines(chip, req_cfg, line_cfg);
    }
    int saved = errno;
    gpiod_request_config_free(req_cfg);
    gpiod_line_config_free(line_cfg);
    gpiod_line_settings_free(settings);
    gpiod_chip_close(chip); /* the request stays valid on its own */
    errno = saved;
    return request;
}

int rig_gpiod_open(const rig_config *cfg, rig_output_backend *out, char *err, size_t err_len)
{
    gpiod_v2 *g = calloc(1, sizeof *g);
    if (g == NULL) {
        snprintf(err, err_len, "gpiod: out of memory");
        return -1;
    }
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        const rig_output_pin *pin = &cfg->pin[o];
        if (!pin->configured)
            continue;
        g->offset[o] = (unsigned int)pin->line;
        g->request[o] = request_one(cfg, pin);
        if (g->request[o] == NULL) {
            snprintf(err, err_len, "gpiod: [output.%s] chip/line: cannot request line %u on '%s': %s",
                     rig_config_output_names[o], (unsigned)pin->line, pin->chip, strerror(errno));
            close_all(g);
            return -1;
        }
    }
    out->impl = g;
    out->apply = apply;
    out->close = close_all;
    return 0;
}
