/* INI configuration of leveler-rig (libinih). */
#define _POSIX_C_SOURCE 200809L
#include "rig_config.h"

#include <errno.h>
#include <stdarg.h>
#include <ini.h>
#include <arpa/inet.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "ini_guard.h"

const char *const rig_channel_names[HAL_ADC_COUNT] = {"height", "p_spring", "p_pipe", "p_acc"};
const char *const rig_output_names[HAL_OUT_COUNT] = {"compressor", "spring_valve", "vent_valve", "acc_valve",
                                                     "status_led"};

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

typedef struct {
    ini_guard guard;       /* the file, its real line numbers, repeated keys */
    rig_config *cfg;
    char *err;
    size_t err_len;
    int failed;
    bool seen_channel[HAL_ADC_COUNT];
    bool seen_watchdog_register;
} parse_state;

__attribute__((format(printf, 4, 5)))
static int fail(parse_state *st, const char *section, const char *key, const char *fmt, ...)
{
    if (st->failed)
        return 0;
    st->failed = 1;
    int n = snprintf(st->err, st->err_len, "%s:%u: [%s] %s: ", st->guard.path, st->guard.line, section, key);
    if (n >= 0 && (size_t)n < st->err_len) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(st->err + n, st->err_len - (size_t)n, fmt, ap);
        va_end(ap);
    }
    return 0;
}

/* Decimal only (a leading 0 is refused: 0777 is neither 777 nor octal 511 here). */
static int parse_int(parse_state *st, const char *section, const char *key, const char *value,
                     long long lo, long long hi, long long *out)
{
    char *end;
    errno = 0;
    const char *digits = value + (value[0] == '-' || value[0] == '+');
    long long v = strtoll(value, &end, 10);
    if (end == value || *end != '\0' || errno == ERANGE || !(digits[0] >= '0' && digits[0] <= '9'))
        return fail(st, section, key, "'%s' is not an integer (decimal, allowed %lld..%lld)", value, lo, hi);
    if (digits[0] == '0' && digits[1] != '\0')
        return fail(st, section, key, "'%s': leading zeros are not allowed (decimal only)", value);
    if (v < lo || v > hi)
        return fail(st, section, key, "%lld is out of range (allowed %lld..%lld)", v, lo, hi);
    *out = v;
    return 1;
}

static int parse_double(parse_state *st, const char *section, const char *key, const char *value,
                        double lo, double hi, double *out)
{
    char *end;
    double v = strtod(value, &end);
    if (end == value || *end != '\0' || !isfinite(v))
        return fail(st, section, key, "'%s' is not a number (allowed %g..%g)", value, lo, hi);
    if (v < lo || v > hi)
        return fail(st, section, key, "%g is out of range (allowed %g..%g)", v, lo, hi);
    *out = v;
    return 1;
}

static int parse_bool(parse_state *st, const char *section, const char *key, const char *value, bool *out)
{
    if (!strcasecmp(value, "true") || !strcasecmp(value, "yes") || !strcmp(value, "1") || !strcasecmp(value, "on"))
        *out = true;
    else if (!strcasecmp(value, "false") || !strcasecmp(value, "no") || !strcmp(value, "0") || !strcasecmp(value, "off"))
        *out = false;
    else
        return fail(st, section, key, "'%s' is not a boolean (allowed true/false)", value);
    return 1;
}

static int parse_text(parse_state *st, const char *section, const char *key, const char *value,
                      char *out, size_t cap)
{
    if (strlen(value) >= cap)
        return fail(st, section, key, "longer than %zu characters", cap - 1);
    if (!ini_utf8_valid(value))
        return fail(st, section, key, "not valid UTF-8");
    memcpy(out, value, strlen(value) + 1);
    return 1;
}

/* One of names[] (a NULL-terminated list) -> its index in *out. */
static int parse_choice(parse_state *st, const char *section, const char *key, const char *value,
                        const char *const names[], int *out)
{
    char allowed[128] = "";
    for (int i = 0; names[i]; i++) {
        if (!strcmp(value, names[i])) {
            *out = i;
            return 1;
        }
        size_t used = strlen(allowed);
        snprintf(allowed + used, sizeof allowed - used, "%s%s", i ? ", " : "", names[i]);
    }
    return fail(st, section, key, "'%s' is not one of %s", value, allowed);
}

/* A numeric IPv4 or IPv6 address, or localhost (= 127.0.0.1), into out (canonical text).
 * inet_pton refuses zero-padded IPv4 parts, so 0127.0.0.1 is an error, not octal. */
int rig_parse_address(const char *value, char *out, size_t cap)
{
    unsigned char bin[16];
    int af = inet_pton(AF_INET, value, bin) == 1 ? AF_INET : inet_pton(AF_INET6, value, bin) == 1 ? AF_INET6 : 0;
    if (!strcmp(value, "localhost") && inet_pton(AF_INET, "127.0.0.1", bin) == 1)
        af = AF_INET;
    if (af == 0 || inet_ntop(af, bin, out, (socklen_t)cap) == NULL)
        return -1;
    return 0;
}

static int parse_address(parse_state *st, const char *section, const char *key, const char *value, char *out,
                         size_t cap)
{
    if (rig_parse_address(value, out, cap) != 0)
        return fail(st, section, key,
                    "'%s' is not a numeric IPv4 or IPv6 address (e.g. 127.0.0.1, ::1, 0.0.0.0; localhost; "
                    "no leading zeros)",
                    value);
    return 1;
}

/* The module's host: an address as above, or a DNS name (resolved when connecting). */
static int parse_host(parse_state *st, const char *section, const char *key, const char *value, char *out,
                      size_t cap)
{
    if (rig_parse_address(value, out, cap) == 0)
        return 1;
    bool name = value[0] != '\0' && strspn(value, "0123456789.") != strlen(value) &&
                strspn(value, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789.-") == strlen(value);
    if (!name)
        return fail(st, section, key, "'%s' is neither a numeric IPv4/IPv6 address (no leading zeros) nor a host name",
                    value);
    return parse_text(st, section, key, value, out, cap);
}

#define INT_FIELD(field, lo, hi)                                                    \
    do {                                                                            \
        long long v_;                                                               \
        if (!parse_int(st, section, key, value, (lo), (hi), &v_))                   \
            return 0;                                                               \
        (field) = v_;                                                               \
        return 1;                                                                   \
    } while (0)

#define CHOICE_FIELD(field, type, ...)                                              \
    do {                                                                            \
        static const char *const names_[] = {__VA_ARGS__, NULL};                    \
        int i_;                                                                     \
        if (!parse_choice(st, section, key, value, names_, &i_))                    \
            return 0;                                                               \
        (field) = (type)i_;                                                         \
        return 1;                                                                   \
    } while (0)

static int channel_key(parse_state *st, rig_channel *ch, const char *section, const char *key,
                       const char *value, double out_lo, double out_hi)
{
    if (!strcmp(key, "enabled"))
        return parse_bool(st, section, key, value, &ch->enabled);
    if (!strcmp(key, "table"))
        CHOICE_FIELD(ch->table, rig_module_table, "input", "holding");
    if (!strcmp(key, "register"))
        INT_FIELD(ch->address, 0, 65535);
    if (!strcmp(key, "signed"))
        return parse_bool(st, section, key, value, &ch->is_signed);
    if (!strcmp(key, "raw_lo"))
        return parse_double(st, section, key, value, -32768, 65535, &ch->raw_lo);
    if (!strcmp(key, "raw_hi"))
        return parse_double(st, section, key, value, -32768, 65535, &ch->raw_hi);
    const char *lo_key = out_hi > HAL_ADC_MAX_COUNTS ? "load_n_lo" : "counts_lo";
    const char *hi_key = out_hi > HAL_ADC_MAX_COUNTS ? "load_n_hi" : "counts_hi";
    if (!strcmp(key, lo_key))
        return parse_double(st, section, key, value, out_lo, out_hi, &ch->out_lo);
    if (!strcmp(key, hi_key))
        return parse_double(st, section, key, value, out_lo, out_hi, &ch->out_hi);
    return fail(st, section, key, "unknown key");
}

static int rig_key(parse_state *st, rig_config *cfg, const char *section, const char *key, const char *value)
{
    if (!strcmp(key, "name"))
        return parse_text(st, section, key, value, cfg->name, sizeof cfg->name);
    if (!strcmp(key, "clock"))
        CHOICE_FIELD(cfg->clock, rig_clock, "monotonic", "lockstep");
    if (!strcmp(key, "run_seconds"))
        return parse_double(st, section, key, value, 0, 1e9, &cfg->run_seconds);
    if (!strcmp(key, "lockstep_time_register"))
        INT_FIELD(cfg->lockstep_time_register, 0, 65534);
    if (!strcmp(key, "lockstep_step_register"))
        INT_FIELD(cfg->lockstep_step_register, 0, 65535);
    return fail(st, section, key, "unknown key");
}

static int sensors_key(parse_state *st, rig_config *cfg, const char *section, const char *key, const char *value)
{
    if (!strcmp(key, "transport"))
        CHOICE_FIELD(cfg->transport, rig_transport, "rtu", "tcp");
    if (!strcmp(key, "device"))
        return parse_text(st, section, key, value, cfg->device, sizeof cfg->device);
    if (!strcmp(key, "baud"))
        INT_FIELD(cfg->baud, 300, 4000000);
    if (!strcmp(key, "parity")) {
        if (strlen(value) != 1 || !strchr("NEO", value[0]))
            return fail(st, section, key, "'%s' is not one of N, E, O", value);
        cfg->parity = value[0];
        return 1;
    }
    if (!strcmp(key, "data_bits"))
        INT_FIELD(cfg->data_bits, 5, 8);
    if (!strcmp(key, "stop_bits"))
        INT_FIELD(cfg->stop_bits, 1, 2);
    if (!strcmp(key, "host"))
        return parse_host(st, section, key, value, cfg->host, sizeof cfg->host);
    if (!strcmp(key, "port"))
        INT_FIELD(cfg->port, 1, 65535);
    if (!strcmp(key, "slave"))
        INT_FIELD(cfg->slave, 0, 247);
    if (!strcmp(key, "timeout_ms"))
        INT_FIELD(cfg->timeout_ms, 1, 10000);
    return fail(st, section, key, "unknown key");
}

static int sensor_section(parse_state *st, rig_config *cfg, const char *section, const char *key, const char *value)
{
    const char *which = section + strlen("sensor.");
    for (int c = 0; c < HAL_ADC_COUNT; c++) {
        if (!strcmp(which, rig_channel_names[c])) {
            if (!st->seen_channel[c]) {
                /* A channel section present in the file is on unless it says otherwise. */
                st->seen_channel[c] = true;
                cfg->channel[c].enabled = true;
            }
            return channel_key(st, &cfg->channel[c], section, key, value, 0, HAL_ADC_MAX_COUNTS);
        }
    }
    if (!strcmp(which, "load")) {
        cfg->load.enabled = true;
        return channel_key(st, &cfg->load, section, key, value, -1e6, 1e6);
    }
    return fail(st, section, key, "unknown sensor (allowed height, p_spring, p_pipe, p_acc, load)");
}

static int outputs_key(parse_state *st, rig_config *cfg, const char *section, const char *key, const char *value)
{
    if (!strcmp(key, "backend"))
        CHOICE_FIELD(cfg->outputs, rig_output_kind, "gpiod", "modbus");
    if (!strcmp(key, "consumer"))
        return parse_text(st, section, key, value, cfg->consumer, sizeof cfg->consumer);
    if (!strcmp(key, "watchdog_ms")) {
        long long v;
        if (!parse_int(st, section, key, value, 0, 65535, &v))
            return 0;
        if (v > 0 && v < RIG_WATCHDOG_MIN_MS)
            return fail(st, section, key, "%lld ms is shorter than a module can honour (0 = off, or %d..65535)", v,
                        RIG_WATCHDOG_MIN_MS);
        cfg->output_watchdog_ms = (uint32_t)v;
        return 1;
    }
    if (!strcmp(key, "watchdog_register")) {
        st->seen_watchdog_register = true;
        INT_FIELD(cfg->output_watchdog_register, 0, 65535);
    }
    return fail(st, section, key, "unknown key");
}

static int output_section(parse_state *st, rig_config *cfg, const char *section, const char *key, const char *value)
{
    const char *which = section + strlen("output.");
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        if (strcmp(which, rig_output_names[o]))
            continue;
        rig_output_pin *pin = &cfg->pin[o];
        pin->configured = true;
        if (!strcmp(key, "chip"))
            return parse_text(st, section, key, value, pin->chip, sizeof pin->chip);
        if (!strcmp(key, "line"))
            INT_FIELD(pin->line, 0, 65535);
        if (!strcmp(key, "active_low"))
            return parse_bool(st, section, key, value, &pin->active_low);
        if (!strcmp(key, "coil"))
            INT_FIELD(pin->coil, 0, 65535);
        return fail(st, section, key, "unknown key");
    }
    return fail(st, section, key, "unknown output (allowed compressor, spring_valve, vent_valve, acc_valve, status_led)");
}

/* "a, b, c" into items (RIG_MAX_WRITERS of 48 bytes): numeric addresses (as
 * [supervision] address) when addresses, else names. */
static int parse_list(parse_state *st, const char *section, const char *key, const char *value,
                      char (*items)[48], uint32_t *count, bool addresses)
{
    char list[RIG_TEXT_MAX * 4];
    snprintf(list, sizeof list, "%s", value);
    *count = 0;
    for (char *save = NULL, *tok = strtok_r(list, ", \t", &save); tok; tok = strtok_r(NULL, ", \t", &save)) {
        if (*count == RIG_MAX_WRITERS)
            return fail(st, section, key, "more than %d %s", RIG_MAX_WRITERS, addresses ? "addresses" : "names");
        if (addresses && !parse_address(st, section, key, tok, items[*count], sizeof items[0]))
            return 0;
        if (!addresses && strlen(tok) >= sizeof items[0])
            return fail(st, section, key, "'%s' longer than %zu bytes", tok, sizeof items[0] - 1);
        if (!addresses)
            snprintf(items[*count], sizeof items[0], "%s", tok);
        (*count)++;
    }
    return 1;
}

static int supervision_key(parse_state *st, rig_config *cfg, const char *section, const char *key, const char *value)
{
    if (!strcmp(key, "enabled"))
        return parse_bool(st, section, key, value, &cfg->supervision_enabled);
    if (!strcmp(key, "address"))
        return parse_address(st, section, key, value, cfg->supervision_address, sizeof cfg->supervision_address);
    if (!strcmp(key, "port"))
        INT_FIELD(cfg->supervision_port, 0, 65535);
    if (!strcmp(key, "port_file"))
        return parse_text(st, section, key, value, cfg->supervision_port_file, sizeof cfg->supervision_port_file);
    if (!strcmp(key, "read_only"))
        return parse_bool(st, section, key, value, &cfg->read_only);
    if (!strcmp(key, "writers"))
        return parse_list(st, section, key, value, cfg->writers, &cfg->writer_count, true);
    if (!strcmp(key, "write_socket"))
        return parse_text(st, section, key, value, cfg->write_socket, sizeof cfg->write_socket);
    if (!strcmp(key, "idle_timeout_s")) {
        long long v;
        if (!parse_int(st, section, key, value, 1, 86400, &v))
            return 0;
        cfg->idle_timeout_ms = (uint32_t)(v * 1000);
        return 1;
    }
    if (!strcmp(key, "idle_timeout_ms"))
        INT_FIELD(cfg->idle_timeout_ms, 10, 86400000);
    if (!strcmp(key, "request_timeout_ms"))
        INT_FIELD(cfg->request_timeout_ms, 10, 60000);
    if (!strcmp(key, "max_clients"))
        INT_FIELD(cfg->max_clients, 1, 64);
    return fail(st, section, key, "unknown key");
}

static int log_key(parse_state *st, rig_config *cfg, const char *section, const char *key, const char *value)
{
    if (!strcmp(key, "path"))
        return parse_text(st, section, key, value, cfg->log_path, sizeof cfg->log_path);
    if (!strcmp(key, "rotate_bytes"))
        INT_FIELD(cfg->log_rotate_bytes, 0, 1LL << 40);
    if (!strcmp(key, "keep_files"))
        INT_FIELD(cfg->log_keep_files, 0, 1000);
    if (!strcmp(key, "load_n"))
        return parse_double(st, section, key, value, 0, 1e6, &cfg->log_load_n);
    return fail(st, section, key, "unknown key");
}


/* [mbaps]: leveler-mbaps (TLS with client certificates, roles). */
static int mbaps_key(parse_state *st, rig_config *cfg, const char *section, const char *key, const char *value)
{
    static const struct {
        const char *key;
        size_t offset;
    } paths[] = {{"port_file", offsetof(rig_config, mbaps_port_file)}, {"cert", offsetof(rig_config, mbaps_cert)},
                 {"key", offsetof(rig_config, mbaps_key)},             {"ca", offsetof(rig_config, mbaps_ca)},
                 {"crl", offsetof(rig_config, mbaps_crl)}};
    for (size_t i = 0; i < sizeof paths / sizeof paths[0]; i++)
        if (!strcmp(key, paths[i].key))
            return parse_text(st, section, key, value, (char *)cfg + paths[i].offset, RIG_TEXT_MAX);
    if (!strcmp(key, "address"))
        return parse_address(st, section, key, value, cfg->mbaps_address, sizeof cfg->mbaps_address);
    if (!strcmp(key, "port"))
        INT_FIELD(cfg->mbaps_port, 0, 65535);
    if (!strcmp(key, "write_roles"))
        return parse_list(st, section, key, value, cfg->mbaps_write_roles, &cfg->mbaps_write_role_count, false);
    return fail(st, section, key, "unknown key");
}

/* [faults]: the auto-clear of link faults (auto_clear.h). */
static int faults_key(parse_state *st, rig_config *cfg, const char *section, const char *key, const char *value)
{
    if (!strcmp(key, "auto_clear_after_s"))
        INT_FIELD(cfg->auto_clear_after_s, 0, 3600);
    if (!strcmp(key, "auto_clear_max_per_hour"))
        INT_FIELD(cfg->auto_clear_max_per_hour, 1, 60);
    return fail(st, section, key, "unknown key (allowed auto_clear_after_s, auto_clear_max_per_hour)");
}

static int handler(void *user, const char *section, const char *key, const char *value)
{
    parse_state *st = user;
    rig_config *cfg = st->cfg;
    if (st->failed)
        return 0;
    if (ini_guard_key(&st->guard, section, key, st->err, st->err_len) != 0) {
        st->failed = 1;
        return 0;
    }
    static const struct {
        const char *name;
        bool prefix;
        int (*fn)(parse_state *, rig_config *, const char *, const char *, const char *);
    } sections[] = {
        {"rig", false, rig_key},           {"sensors", false, sensors_key},         {"sensor.", true, sensor_section},
        {"outputs", false, outputs_key},   {"output.", true, output_section},       {"supervision", false, supervision_key},
        {"log", false, log_key},           {"faults", false, faults_key},
        {"mbaps", false, mbaps_key},
    };
    for (size_t i = 0; i < sizeof sections / sizeof sections[0]; i++) {
        bool match = sections[i].prefix ? !strncmp(section, sections[i].name, strlen(sections[i].name))
                                        : !strcmp(section, sections[i].name);
        if (match)
            return sections[i].fn(st, cfg, section, key, value);
    }
    return fail(st, section, key, "unknown section");
}

static int check_whole(const char *path, const rig_config *cfg, bool seen_watchdog_register, char *err,
                       size_t err_len);

int rig_config_load(const char *path, rig_config *cfg, char *err, size_t err_len)
{
    parse_state st = {.cfg = cfg, .err = err, .err_len = err_len};
    if (ini_guard_open(&st.guard, path, err, err_len) != 0)
        return -1;
    int rc = ini_parse_stream(ini_guard_reader, &st.guard, handler, &st);
    if (!st.failed && ini_guard_finish(&st.guard, rc, err, err_len) != 0)
        st.failed = 1;
    ini_guard_close(&st.guard);
    if (st.failed)
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
            snprintf(err, err_len, "%s: [sensor.%s] raw_lo, raw_hi: must differ", path, rig_channel_names[c]);
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
                     rig_output_names[o]);
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
