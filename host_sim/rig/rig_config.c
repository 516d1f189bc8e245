/* INI configuration of leveler-rig: its defaults (boards/linux-rig/rig-defaults.ini,
 * compiled in), the load (the one INI reader, ini_table.h, with the schema of
 * rig_config_schema.c) and the checks of the whole. */
#define _POSIX_C_SOURCE 200809L
#include "rig_config.h"
#include "rig_config_schema.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* boards/linux-rig/rig-defaults.ini, compiled in (rig_config_builtin.c, made by CMake from the file). */
extern const char rig_config_builtin_ini[];
#define BUILTIN_NAME "rig-defaults.ini (built in)"

/* path (or text, named path) over cfg: 0, or -1 with err. */
static int read_over(rig_config *cfg, rig_config_state *st, const char *path, const char *text, char *err,
                     size_t err_len)
{
    ini_load load = {.table = &rig_config_table, .config = cfg, .user = st, .err = err, .err_len = err_len};
    return text ? ini_table_read_text(&load, path, text) : ini_table_read(&load, path);
}

void rig_config_defaults(rig_config *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    /* No INI value says "not given": a run log without [sensor.load] needs load_n (check_whole). */
    cfg->log_load_n = NAN;
    rig_config_state st = {0};
    char err[512];
    if (read_over(cfg, &st, BUILTIN_NAME, rig_config_builtin_ini, err, sizeof err) != 0) {
        fprintf(stderr, "leveler: the rig's built-in defaults do not load: %s\n", err);
        abort(); /* the build checks them: tests/rig/test_rig_defaults.c */
    }
    /* configured says the config file named the output (check_whole); the built-in
     * [output.X] give only what the output takes when it is named. */
    for (int o = 0; o < HAL_OUT_COUNT; o++)
        cfg->pin[o].configured = false;
}

static int check_whole(const char *path, const rig_config *cfg, bool seen_watchdog_register, char *err,
                       size_t err_len);

int rig_config_load(const char *path, rig_config *cfg, char *err, size_t err_len)
{
    rig_config_state st = {0};
    if (read_over(cfg, &st, path, NULL, err, err_len) != 0)
        return -1;
    return check_whole(path, cfg, st.seen_watchdog_register, err, err_len);
}

/* Consistency of the whole file; no single line to name. */
static int check_whole(const char *path, const rig_config *cfg, bool seen_watchdog_register, char *err,
                       size_t err_len)
{
    if (cfg->transport == RIG_TRANSPORT_TCP && cfg->host[0] == '\0') {
        snprintf(err, err_len, "%s: [sensors] host: required with transport = tcp", path);
        return -1;
    }
    if (cfg->transport == RIG_TRANSPORT_RTU && cfg->device[0] == '\0') {
        snprintf(err, err_len, "%s: [sensors] device: required with transport = rtu", path);
        return -1;
    }
    for (int c = 0; c < HAL_ADC_COUNT; c++) {
        if (cfg->channel[c].enabled && cfg->channel[c].raw_lo == cfg->channel[c].raw_hi) {
            snprintf(err, err_len, "%s: [sensor.%s] raw_lo, raw_hi: must differ", path, rig_config_channel_names[c]);
            return -1;
        }
    }
    if (cfg->load.enabled && cfg->load.raw_lo == cfg->load.raw_hi) {
        snprintf(err, err_len, "%s: [sensor.load] raw_lo, raw_hi: must differ", path);
        return -1;
    }
    for (int o = 0; o < HAL_OUT_STATUS_LED; o++) {
        if (!cfg->pin[o].configured) {
            snprintf(err, err_len, "%s: [output.%s]: missing (every valve and the compressor need one)", path,
                     rig_config_output_names[o]);
            return -1;
        }
    }
    if (cfg->clock == RIG_CLOCK_LOCKSTEP && cfg->outputs == RIG_OUTPUTS_GPIOD) {
        snprintf(err, err_len, "%s: [rig] clock: lockstep needs [outputs] backend = modbus (a served plant)", path);
        return -1;
    }
    if (cfg->log_path[0] && !cfg->load.enabled && !isfinite(cfg->log_load_n)) {
        snprintf(err, err_len, "%s: [log] load_n: required when there is no [sensor.load] (the log needs a load)",
                 path);
        return -1;
    }
    if (cfg->write_socket[0] && cfg->writer_count > 0) {
        snprintf(err, err_len, "%s: [supervision] writers, write_socket: one or the other (with write_socket only "
                 "its clients write: a source address is no proof of who sent it)", path);
        return -1;
    }
    /* gpiod lines have no module watchdog (the unit's ExecStopPost=--safe-outputs covers them): ignored there. */
    if (cfg->output_watchdog_ms > 0 && cfg->outputs == RIG_OUTPUTS_MODBUS && !seen_watchdog_register) {
        snprintf(err, err_len, "%s: [outputs] watchdog_ms: needs the module's watchdog_register", path);
        return -1;
    }
    return 0;
}
