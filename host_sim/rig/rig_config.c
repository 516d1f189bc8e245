/* INI configuration of leveler-rig: its defaults, the load (the one INI reader,
 * ini_table.h, with the schema of rig_config_schema.c) and the checks of the whole. */
#define _POSIX_C_SOURCE 200809L
#include "rig_config.h"
#include "rig_config_schema.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

void rig_config_defaults(rig_config *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    snprintf(cfg->name, sizeof cfg->name, "rig");
    cfg->clock = RIG_CLOCK_MONOTONIC;
    cfg->lockstep_time_register = 16;
    cfg->lockstep_step_register = 0;
    cfg->transport = RIG_TRANSPORT_RTU;
    snprintf(cfg->device, sizeof cfg->device, "/dev/ttyUSB0");
    cfg->baud = 19200;
    cfg->parity = 'N';
    cfg->data_bits = 8;
    cfg->stop_bits = 1;
    snprintf(cfg->host, sizeof cfg->host, "127.0.0.1");
    cfg->port = 502;
    cfg->slave = 1;
    cfg->timeout_ms = 5;
    for (int c = 0; c < HAL_ADC_COUNT; c++) {
        rig_channel *ch = &cfg->channel[c];
        ch->enabled = c != HAL_ADC_P_ACC; /* the accumulator is optional */
        ch->table = RIG_TABLE_INPUT;
        ch->address = (uint16_t)c;
        ch->raw_lo = 0;
        ch->raw_hi = HAL_ADC_MAX_COUNTS;
        ch->out_lo = 0;
        ch->out_hi = HAL_ADC_MAX_COUNTS;
    }
    cfg->load.enabled = false;
    cfg->load.table = RIG_TABLE_INPUT;
    cfg->load.address = 4;
    cfg->load.raw_lo = 0;
    cfg->load.raw_hi = 1;
    cfg->load.out_lo = 0;
    cfg->load.out_hi = 1;
    cfg->outputs = RIG_OUTPUTS_GPIOD;
    snprintf(cfg->consumer, sizeof cfg->consumer, "leveler-rig");
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        snprintf(cfg->pin[o].chip, sizeof cfg->pin[o].chip, "gpiochip0");
        cfg->pin[o].coil = (uint16_t)o;
    }
    cfg->supervision_enabled = true;
    snprintf(cfg->supervision_address, sizeof cfg->supervision_address, "127.0.0.1");
    cfg->supervision_port = 1502;
    cfg->read_only = false;
    cfg->idle_timeout_ms = 60000;
    cfg->request_timeout_ms = 1000;
    cfg->max_clients = 4;
    cfg->log_rotate_bytes = 0;
    cfg->log_keep_files = 5;
    cfg->log_load_n = NAN;
    snprintf(cfg->mbaps_address, sizeof cfg->mbaps_address, "0.0.0.0");
    cfg->mbaps_port = 802;
    cfg->mbaps_write_role_count = 1;
    snprintf(cfg->mbaps_write_roles[0], sizeof cfg->mbaps_write_roles[0], "Operator");
    cfg->auto_clear_after_s = 0;
    cfg->auto_clear_max_per_hour = 6;
}

static int check_whole(const char *path, const rig_config *cfg, bool seen_watchdog_register, char *err,
                       size_t err_len);

int rig_config_load(const char *path, rig_config *cfg, char *err, size_t err_len)
{
    rig_config_state st = {0};
    ini_load load = {.table = &rig_config_table, .config = cfg, .user = &st, .err = err, .err_len = err_len};
    if (ini_table_read(&load, path) != 0)
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
