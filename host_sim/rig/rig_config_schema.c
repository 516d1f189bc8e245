/*
 * The rig config's schema (boards/linux-rig/rig-defaults.ini has every key with
 * its meaning and default): its table of fields for the one INI reader (ini_table.h), the
 * [sensor.X] and [output.X] instances, and the keys read by hand (addresses,
 * lists, the parity letter, the module watchdog).
 */
#define _POSIX_C_SOURCE 200809L
#include "rig_config_schema.h"

#include <arpa/inet.h>
#include <stdio.h>
#include <string.h>

const char *const rig_config_channel_names[HAL_ADC_COUNT] = {"height", "p_spring", "p_pipe", "p_acc"};
const char *const rig_config_output_names[HAL_OUT_COUNT] = {"compressor", "spring_valve", "vent_valve", "acc_valve",
                                                            "status_led"};

/* A numeric IPv4 or IPv6 address, or localhost (= 127.0.0.1), into out (canonical text).
 * inet_pton refuses zero-padded IPv4 parts, so 0127.0.0.1 is an error, not octal. */
int rig_config_parse_address(const char *value, char *out, size_t cap)
{
    unsigned char bin[16];
    int af = inet_pton(AF_INET, value, bin) == 1 ? AF_INET : inet_pton(AF_INET6, value, bin) == 1 ? AF_INET6 : 0;
    if (!strcmp(value, "localhost") && inet_pton(AF_INET, "127.0.0.1", bin) == 1)
        af = AF_INET;
    if (af == 0 || inet_ntop(af, bin, out, (socklen_t)cap) == NULL)
        return -1;
    return 0;
}

static int fail_address(ini_file *r, const char *section, const char *key, const char *value)
{
    return ini_file_fail(r, section, key, NULL,
                         "'%s' is not a numeric IPv4 or IPv6 address (e.g. 127.0.0.1, ::1, 0.0.0.0; localhost; "
                         "no leading zeros)",
                         value);
}

static int key_address(ini_file *r, const ini_field *f, void *obj, const char *section, const char *key,
                       const char *value)
{
    if (rig_config_parse_address(value, (char *)obj + f->offset, f->size) != 0)
        return fail_address(r, section, key, value);
    return 1;
}

/* The module's host: an address as above, or a DNS name (resolved when connecting). */
static int key_host(ini_file *r, const ini_field *f, void *obj, const char *section, const char *key,
                    const char *value)
{
    char *out = (char *)obj + f->offset;
    if (rig_config_parse_address(value, out, f->size) == 0)
        return 1;
    bool name = value[0] != '\0' && strspn(value, "0123456789.") != strlen(value) &&
                strspn(value, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789.-") == strlen(value);
    if (!name)
        return ini_file_fail(r, section, key, NULL,
                             "'%s' is neither a numeric IPv4/IPv6 address (no leading zeros) nor a host name", value);
    if (strlen(value) >= f->size)
        return ini_file_fail(r, section, key, NULL, "longer than %zu characters", f->size - 1);
    memcpy(out, value, strlen(value) + 1);
    return 1;
}

static int key_parity(ini_file *r, const ini_field *f, void *obj, const char *section, const char *key,
                      const char *value)
{
    if (strlen(value) != 1 || !strchr("NEO", value[0]))
        return ini_file_fail(r, section, key, NULL, "'%s' is not one of N, E, O", value);
    *((char *)obj + f->offset) = value[0];
    return 1;
}

/* "a, b, c" into items (RIG_MAX_WRITERS of 48 bytes): numeric addresses (as
 * [supervision] address) when addresses, else names. */
static int read_list(ini_file *r, const char *section, const char *key, const char *value, char (*items)[48],
                     uint32_t *count, bool addresses)
{
    char list[RIG_TEXT_MAX * 4];
    snprintf(list, sizeof list, "%s", value);
    *count = 0;
    for (char *save = NULL, *tok = strtok_r(list, ", \t", &save); tok; tok = strtok_r(NULL, ", \t", &save)) {
        if (*count == RIG_MAX_WRITERS)
            return ini_file_fail(r, section, key, NULL, "more than %d %s", RIG_MAX_WRITERS,
                                 addresses ? "addresses" : "names");
        if (addresses && rig_config_parse_address(tok, items[*count], sizeof items[0]) != 0)
            return fail_address(r, section, key, tok);
        if (!addresses && strlen(tok) >= sizeof items[0])
            return ini_file_fail(r, section, key, NULL, "'%s' longer than %zu bytes", tok, sizeof items[0] - 1);
        if (!addresses)
            snprintf(items[*count], sizeof items[0], "%s", tok);
        (*count)++;
    }
    return 1;
}

static int key_writers(ini_file *r, const ini_field *f, void *obj, const char *section, const char *key,
                       const char *value)
{
    (void)f;
    rig_config *cfg = obj;
    return read_list(r, section, key, value, cfg->writers, &cfg->writer_count, true);
}

static int key_write_roles(ini_file *r, const ini_field *f, void *obj, const char *section, const char *key,
                           const char *value)
{
    (void)f;
    rig_config *cfg = obj;
    return read_list(r, section, key, value, cfg->mbaps_write_roles, &cfg->mbaps_write_role_count, false);
}

static int key_idle_timeout_s(ini_file *r, const ini_field *f, void *obj, const char *section, const char *key,
                              const char *value)
{
    long long v;
    if (!ini_file_decimal(r, section, key, value, 1, 86400, &v))
        return 0;
    *(uint32_t *)((char *)obj + f->offset) = (uint32_t)(v * 1000);
    return 1;
}

static int key_watchdog_ms(ini_file *r, const ini_field *f, void *obj, const char *section, const char *key,
                           const char *value)
{
    long long v;
    if (!ini_file_decimal(r, section, key, value, 0, 65535, &v))
        return 0;
    if (v > 0 && v < RIG_WATCHDOG_MIN_MS)
        return ini_file_fail(r, section, key, NULL,
                             "%lld ms is shorter than a module can honour (0 = off, or %d..65535)", v,
                             RIG_WATCHDOG_MIN_MS);
    *(uint32_t *)((char *)obj + f->offset) = (uint32_t)v;
    return 1;
}

/* A [sensor.X] section of the file turns its channel on at its first key: on
 * unless the section says enabled = false (read after this, wherever it stands). */
static rig_channel *seen(rig_config_state *st, int i, rig_channel *ch)
{
    if (!st->seen_channel[i])
        ch->enabled = st->seen_channel[i] = true;
    return ch;
}

/* [sensor.X] and [output.X]: the channel (the load's too) or the pin. */
static void *instance(ini_file *r, const char *section, const char *group, const char *key, int *index)
{
    (void)group;
    rig_config *cfg = r->load->config;
    rig_config_state *st = r->load->user;
    const char *which = strchr(section, '.') + 1;
    bool sensor = !strncmp(section, "sensor.", 7);
    for (int i = 0; sensor && i < HAL_ADC_COUNT; i++)
        if (!strcmp(which, rig_config_channel_names[i])) {
            *index = i;
            return seen(st, i, &cfg->channel[i]);
        }
    if (sensor && !strcmp(which, "load")) {
        *index = HAL_ADC_COUNT;
        return seen(st, HAL_ADC_COUNT, &cfg->load);
    }
    for (int o = 0; !sensor && o < HAL_OUT_COUNT; o++)
        if (!strcmp(which, rig_config_output_names[o])) {
            cfg->pin[o].configured = true;
            *index = o;
            return &cfg->pin[o];
        }
    ini_file_fail(r, section, key, NULL, sensor ? "unknown sensor (allowed height, p_spring, p_pipe, p_acc, load)"
                                                : "unknown output (allowed compressor, spring_valve, vent_valve, "
                                                  "acc_valve, status_led)");
    return NULL;
}

static void stored(ini_file *r, const ini_field *f, int index, const ini_unit *u)
{
    (void)index;
    (void)u;
    if (!strcmp(f->section, "outputs") && !strcmp(f->key, "watchdog_register"))
        ((rig_config_state *)r->load->user)->seen_watchdog_register = true;
}

static const char *const clocks[] = {"monotonic", "lockstep", NULL};
static const char *const transports[] = {"rtu", "tcp", NULL};
static const char *const tables[] = {"input", "holding", NULL};
static const char *const backends[] = {"gpiod", "modbus", NULL};

#define C(m) offsetof(rig_config, m)
#define CH(m) offsetof(rig_channel, m)
#define PIN(m) offsetof(rig_output_pin, m)
#define TEXT(s, k, off) {s, k, INI_TEXT, INI_F64, off, 0, 0, 0, RIG_TEXT_MAX, NULL, NULL}
#define DEC(s, k, store, off, lo, hi) {s, k, INI_DECIMAL, store, off, lo, hi, 0, 0, NULL, NULL}
#define REAL(s, k, off, lo, hi) {s, k, INI_REAL, INI_F64, off, lo, hi, 0, 0, NULL, NULL}
#define BOOL(s, k, off) {s, k, INI_BOOL, INI_F64, off, 0, 0, 0, 0, NULL, NULL}
#define CHOICE(s, k, off, names) {s, k, INI_CHOICE, INI_F64, off, 0, 0, 0, 0, names, NULL}
#define HAND(s, k, off, size, fn) {s, k, INI_CUSTOM, INI_F64, off, 0, 0, 0, size, NULL, fn}
/* A channel's keys: out_lo/out_hi are ADC counts, or N for the load cell. */
#define CHANNEL(s, lo_key, hi_key, lo, hi)                                                                            \
    BOOL(s, "enabled", CH(enabled)), CHOICE(s, "table", CH(table), tables),                                         \
        DEC(s, "register", INI_U16, CH(address), 0, 65535), BOOL(s, "signed", CH(is_signed)),                       \
        REAL(s, "raw_lo", CH(raw_lo), -32768, 65535), REAL(s, "raw_hi", CH(raw_hi), -32768, 65535),                 \
        REAL(s, lo_key, CH(out_lo), lo, hi), REAL(s, hi_key, CH(out_hi), lo, hi)

static const ini_field fields[] = {
    TEXT("rig", "name", C(name)),
    CHOICE("rig", "clock", C(clock), clocks),
    REAL("rig", "run_seconds", C(run_seconds), 0, 1e9),
    DEC("rig", "lockstep_time_register", INI_U16, C(lockstep_time_register), 0, 65534),
    DEC("rig", "lockstep_step_register", INI_U16, C(lockstep_step_register), 0, 65535),
    CHOICE("sensors", "transport", C(transport), transports),
    TEXT("sensors", "device", C(device)),
    DEC("sensors", "baud", INI_U32, C(baud), 300, 4000000),
    HAND("sensors", "parity", C(parity), 1, key_parity),
    DEC("sensors", "data_bits", INI_U8, C(data_bits), 5, 8),
    DEC("sensors", "stop_bits", INI_U8, C(stop_bits), 1, 2),
    HAND("sensors", "host", C(host), RIG_TEXT_MAX, key_host),
    DEC("sensors", "port", INI_U16, C(port), 1, 65535),
    DEC("sensors", "slave", INI_U8, C(slave), 0, 247),
    DEC("sensors", "timeout_ms", INI_U32, C(timeout_ms), 1, 10000),
    CHANNEL("sensor.load", "load_n_lo", "load_n_hi", -1e6, 1e6),
    CHANNEL("sensor.", "counts_lo", "counts_hi", 0, HAL_ADC_MAX_COUNTS),
    CHOICE("outputs", "backend", C(outputs), backends),
    TEXT("outputs", "consumer", C(consumer)),
    HAND("outputs", "watchdog_ms", C(output_watchdog_ms), 0, key_watchdog_ms),
    DEC("outputs", "watchdog_register", INI_U16, C(output_watchdog_register), 0, 65535),
    TEXT("output.", "chip", PIN(chip)),
    DEC("output.", "line", INI_U32, PIN(line), 0, 65535),
    BOOL("output.", "active_low", PIN(active_low)),
    DEC("output.", "coil", INI_U16, PIN(coil), 0, 65535),
    BOOL("supervision", "enabled", C(supervision_enabled)),
    HAND("supervision", "address", C(supervision_address), RIG_TEXT_MAX, key_address),
    DEC("supervision", "port", INI_U16, C(supervision_port), 0, 65535),
    TEXT("supervision", "port_file", C(supervision_port_file)),
    BOOL("supervision", "read_only", C(read_only)),
    HAND("supervision", "writers", 0, 0, key_writers),
    TEXT("supervision", "write_socket", C(write_socket)),
    HAND("supervision", "idle_timeout_s", C(idle_timeout_ms), 0, key_idle_timeout_s),
    DEC("supervision", "idle_timeout_ms", INI_U32, C(idle_timeout_ms), 10, 86400000),
    DEC("supervision", "request_timeout_ms", INI_U32, C(request_timeout_ms), 10, 60000),
    DEC("supervision", "max_clients", INI_U32, C(max_clients), 1, 64),
    TEXT("log", "path", C(log_path)),
    DEC("log", "rotate_bytes", INI_U64, C(log_rotate_bytes), 0, 1LL << 40),
    DEC("log", "keep_files", INI_U32, C(log_keep_files), 0, 1000),
    REAL("log", "load_n", C(log_load_n), 0, 1e6),
    DEC("faults", "auto_clear_after_s", INI_U32, C(auto_clear_after_s), 0, 3600),
    DEC("faults", "auto_clear_max_per_hour", INI_U32, C(auto_clear_max_per_hour), 1, 60),
    TEXT("mbaps", "port_file", C(mbaps_port_file)),
    TEXT("mbaps", "cert", C(mbaps_cert)),
    TEXT("mbaps", "key", C(mbaps_key)),
    TEXT("mbaps", "ca", C(mbaps_ca)),
    TEXT("mbaps", "crl", C(mbaps_crl)),
    HAND("mbaps", "address", C(mbaps_address), RIG_TEXT_MAX, key_address),
    DEC("mbaps", "port", INI_U16, C(mbaps_port), 0, 65535),
    HAND("mbaps", "write_roles", 0, 0, key_write_roles),
};

const ini_table rig_config_table = {
    .fields = fields,
    .field_count = sizeof fields / sizeof fields[0],
    .max_instances = HAL_ADC_COUNT + 1 > HAL_OUT_COUNT ? HAL_ADC_COUNT + 1 : HAL_OUT_COUNT,
    .instance = instance,
    .stored = stored,
};
