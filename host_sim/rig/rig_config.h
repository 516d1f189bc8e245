/*
 * leveler-rig configuration: one INI file, read by the one INI reader
 * (ini_table.h); see boards/linux-rig/rig-defaults.ini for every key with its meaning and default, rig.ini for
 * an example. Parse errors name the file, the line, the [section] key and, for numbers, the allowed range.
 */
#ifndef LEVELER_RIG_CONFIG_H
#define LEVELER_RIG_CONFIG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "leveler/hal.h"

#define RIG_TEXT_MAX 256
#define RIG_MAX_WRITERS 16
/* The shortest module watchdog the rig can feed: it re-sends the outputs every
 * watchdog_ms / 4 (at least every 2 ticks at 100 ms), so one late tick or one
 * failed request (timeout_ms) does not trip it; modules count in 10-100 ms steps. */
#define RIG_WATCHDOG_MIN_MS 100

typedef enum { RIG_CLOCK_MONOTONIC = 0, RIG_CLOCK_LOCKSTEP = 1 } rig_clock;
typedef enum { RIG_TRANSPORT_RTU = 0, RIG_TRANSPORT_TCP = 1 } rig_transport;
typedef enum { RIG_OUTPUTS_GPIOD = 0, RIG_OUTPUTS_MODBUS = 1 } rig_output_kind;
typedef enum { RIG_TABLE_INPUT = 0, RIG_TABLE_HOLDING = 1 } rig_module_table;

/* One analog channel of the input module: a register whose raw value maps
 * linearly raw_lo..raw_hi -> out_lo..out_hi (ADC counts, or N for the load). */
typedef struct {
    bool enabled;
    rig_module_table table;
    uint16_t address;
    bool is_signed;   /* raw register read as int16 */
    double raw_lo, raw_hi;
    double out_lo, out_hi;
} rig_channel;

typedef struct {
    bool configured;
    char chip[RIG_TEXT_MAX]; /* gpiod: name, number or /dev path */
    uint32_t line;
    bool active_low;
    uint16_t coil;           /* modbus backend: coil address on the module */
} rig_output_pin;

typedef struct {
    char name[RIG_TEXT_MAX]; /* config name written into the run log */
    rig_clock clock;
    double run_seconds;       /* 0 = until SIGINT/SIGTERM */
    uint16_t lockstep_time_register;  /* input register pair: module clock, ms, high word first */
    uint16_t lockstep_step_register;  /* holding register: writing N advances the module N ms */

    rig_transport transport;
    char device[RIG_TEXT_MAX];
    uint32_t baud;
    char parity;              /* 'N', 'E', 'O' */
    uint8_t data_bits, stop_bits;
    char host[RIG_TEXT_MAX];
    uint16_t port;
    uint8_t slave;
    uint32_t timeout_ms;      /* per Modbus request to the module */

    rig_channel channel[HAL_ADC_COUNT];
    rig_channel load;         /* optional load cell, out_* in N */

    rig_output_kind outputs;
    char consumer[RIG_TEXT_MAX];
    rig_output_pin pin[HAL_OUT_COUNT];
    uint32_t output_watchdog_ms;       /* modbus backend: the module's communication watchdog, 0 = none */
    uint16_t output_watchdog_register; /* holding register the module takes it in */

    bool supervision_enabled;
    char supervision_address[RIG_TEXT_MAX]; /* a numeric IPv4/IPv6 address (localhost -> 127.0.0.1) */
    uint16_t supervision_port;        /* 0 = an ephemeral port chosen by the kernel */
    char supervision_port_file[RIG_TEXT_MAX]; /* if set, the bound port is written here */
    bool read_only;
    uint32_t idle_timeout_ms;
    uint32_t request_timeout_ms;      /* a request's first to last byte */
    uint32_t max_clients;
    uint32_t writer_count;            /* 0 = every client may write (unless read_only) */
    char writers[RIG_MAX_WRITERS][48]; /* numeric addresses allowed to write */
    char write_socket[RIG_TEXT_MAX];  /* Unix socket whose clients may write (file permissions guard it);
                                         when set, no TCP client writes (leveler-mbaps connects here) */

    /* [mbaps]: leveler-mbaps, Modbus/TCP Security in front of write_socket */
    char mbaps_address[RIG_TEXT_MAX];
    uint16_t mbaps_port;              /* 0 = kernel's choice (tests), 802 by the specification */
    char mbaps_port_file[RIG_TEXT_MAX];
    char mbaps_cert[RIG_TEXT_MAX], mbaps_key[RIG_TEXT_MAX], mbaps_ca[RIG_TEXT_MAX], mbaps_crl[RIG_TEXT_MAX];
    uint32_t mbaps_write_role_count;
    char mbaps_write_roles[RIG_MAX_WRITERS][48]; /* role extension values that may write */

    char log_path[RIG_TEXT_MAX];      /* empty = no run log */
    uint64_t log_rotate_bytes;
    uint32_t log_keep_files;
    double log_load_n;                /* logged load when there is no load channel */

    uint32_t auto_clear_after_s;      /* [faults]: link faults cleared after this long of valid sensors; 0 = off */
    uint32_t auto_clear_max_per_hour; /* at most this many auto-clears in any hour */
} rig_config;

/* The defaults: boards/linux-rig/rig-defaults.ini, compiled in (aborts if it does not load). */
void rig_config_defaults(rig_config *cfg);

/* Parse path over the defaults, then check the whole. 0 on success; otherwise
 * -1 with "file:line: [section] key: what is wrong" in err. A repeated key or
 * section, a directory, an over-long line, a non-decimal or zero-padded
 * integer, an address that is not numeric IPv4/IPv6 (or localhost) and a name
 * that is not UTF-8 are errors. */
int rig_config_load(const char *path, rig_config *cfg, char *err, size_t err_len);

/* A numeric IPv4/IPv6 address or localhost -> canonical text in out; -1 otherwise. */
int rig_config_parse_address(const char *value, char *out, size_t cap);

/* Names used in the config for the HAL channels and outputs. */
extern const char *const rig_config_channel_names[HAL_ADC_COUNT];
extern const char *const rig_config_output_names[HAL_OUT_COUNT];

#endif
