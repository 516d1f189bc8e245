/*
 * The firmware's Modbus RTU slave against libmodbus as master, over a
 * pseudo-terminal pair. The slave thread runs the firmware as a board would
 * (leveler_app_init, then leveler_modbus_rtu_poll() in a loop and
 * leveler_app_tick() every 10 ms) on the pty HAL; the test thread is the
 * master (19200 8E1). Expectations come from registers.json (defaults, table
 * sizes), the pty HAL (ADC counts, outputs) and the Modbus specification
 * (exception codes libmodbus decodes).
 */
#define _DEFAULT_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <pty.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>
#include <cjson/cJSON.h>
#include <modbus.h>

#include "hal_pty.h"
#include "leveler/app.h"
#include "leveler/modbus_rtu.h"

#define SLAVE_ADDRESS 1
#define RESPONSE_TIMEOUT_S 1u         /* generous: the host is shared and runs ASan */
#define SILENCE_TIMEOUT_US 250000u   /* how long a "no reply" case waits */

/* ---- registers.json: the independent expectation ------------------------- */

typedef struct {
    char name[48];
    char table[12];
    int address;
    int words;       /* 2 for int32/uint32 */
    long long def;   /* default, holding registers only */
    int has_default;
} reg_spec;

static reg_spec specs[128];
static int spec_count;

static void load_register_map(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        fprintf(stderr, "%s: cannot open\n", path);
        exit(1);
    }
    static char text[256 * 1024];
    const size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = '\0';
    cJSON *root = cJSON_Parse(text);
    const cJSON *regs = cJSON_GetObjectItemCaseSensitive(root, "registers");
    if (!cJSON_IsArray(regs)) {
        fprintf(stderr, "%s: no \"registers\" array\n", path);
        exit(1);
    }
    const cJSON *r;
    cJSON_ArrayForEach(r, regs)
    {
        reg_spec *s = &specs[spec_count++];
        snprintf(s->name, sizeof s->name, "%s", cJSON_GetObjectItem(r, "name")->valuestring);
        snprintf(s->table, sizeof s->table, "%s", cJSON_GetObjectItem(r, "table")->valuestring);
        s->address = cJSON_GetObjectItem(r, "address")->valueint;
        const char *type = cJSON_GetObjectItem(r, "type")->valuestring;
        s->words = (strcmp(type, "int32") == 0 || strcmp(type, "uint32") == 0) ? 2 : 1;
        const cJSON *d = cJSON_GetObjectItem(r, "default");
        s->has_default = cJSON_IsNumber(d);
        s->def = s->has_default ? (long long)d->valuedouble : 0;
    }
    cJSON_Delete(root);
}

/* One past the highest address of a table. */
static int table_size(const char *table)
{
    int size = 0;
    for (int i = 0; i < spec_count; i++) {
        if (strcmp(specs[i].table, table) == 0 && specs[i].address + specs[i].words > size) {
            size = specs[i].address + specs[i].words;
        }
    }
    return size;
}

static const reg_spec *spec_named(const char *name)
{
    for (int i = 0; i < spec_count; i++) {
        if (strcmp(specs[i].name, name) == 0) {
            return &specs[i];
        }
    }
    fail_msg("registers.json has no register %s", name);
    return NULL;
}

/* ---- the slave: firmware on the pty HAL, in its own thread ----------------- */

static atomic_bool slave_stop;
static pthread_t slave_thread;
static int pty_master = -1;
static int pty_slave = -1;
static char pty_path[128];

static void *slave_main(void *arg)
{
    (void)arg;
    leveler_app_init();
    leveler_modbus_rtu_init();
    uint32_t next_tick_ms = hal_now_ms() + LEVELER_TICK_MS;
    const struct timespec nap = {0, 100000}; /* 0.1 ms: well inside the 3 ms gap */
    while (!atomic_load(&slave_stop)) {
        leveler_modbus_rtu_poll();
        if ((int32_t)(hal_now_ms() - next_tick_ms) >= 0) {
            leveler_app_tick();
            next_tick_ms += LEVELER_TICK_MS;
        }
        nanosleep(&nap, NULL);
    }
    return NULL;
}

static modbus_t *ctx;

static int start_slave_and_master(void **state)
{
    (void)state;
    struct termios raw;
    memset(&raw, 0, sizeof raw);
    cfmakeraw(&raw); /* no echo, no line discipline: bytes pass as they are */
    if (openpty(&pty_master, &pty_slave, pty_path, &raw, NULL) != 0) {
        perror("openpty");
        return -1;
    }
    fcntl(pty_master, F_SETFL, fcntl(pty_master, F_GETFL) | O_NONBLOCK);
    hal_pty_attach(pty_master);
    if (pthread_create(&slave_thread, NULL, slave_main, NULL) != 0) {
        return -1;
    }
    ctx = modbus_new_rtu(pty_path, 19200, 'E', 8, 1);
    if (ctx == NULL || modbus_connect(ctx) != 0) {
        fprintf(stderr, "libmodbus on %s: %s\n", pty_path, modbus_strerror(errno));
        return -1;
    }
    modbus_set_slave(ctx, SLAVE_ADDRESS);
    modbus_set_response_timeout(ctx, RESPONSE_TIMEOUT_S, 0);
    const struct timespec settle = {0, 100 * 1000000}; /* ten ticks: sensors sampled */
    nanosleep(&settle, NULL);
    return 0;
}

static int stop_slave_and_master(void **state)
{
    (void)state;
    modbus_close(ctx);
    modbus_free(ctx);
    atomic_store(&slave_stop, true);
    pthread_join(slave_thread, NULL);
    close(pty_slave);
    close(pty_master);
    return 0;
}

/* ---- helpers --------------------------------------------------------------- */

static long long read_holding(const char *name)
{
    const reg_spec *s = spec_named(name);
    uint16_t w[2] = {0, 0};
    assert_int_equal(modbus_read_registers(ctx, s->address, s->words, w), s->words);
    if (s->words == 1) {
        return w[0];
    }
    return (int32_t)(((uint32_t)w[0] << 16) | w[1]); /* high word first */
}

static int write_holding(const char *name, long long value)
{
    const reg_spec *s = spec_named(name);
    if (s->words == 1) {
        return modbus_write_register(ctx, s->address, (uint16_t)value);
    }
    const uint32_t u = (uint32_t)(int32_t)value;
    const uint16_t w[2] = {(uint16_t)(u >> 16), (uint16_t)(u & 0xFFFFu)};
    return modbus_write_registers(ctx, s->address, 2, w);
}

static uint16_t read_input(const char *name)
{
    const reg_spec *s = spec_named(name);
    uint16_t w = 0;
    assert_int_equal(modbus_read_input_registers(ctx, s->address, 1, &w), 1);
    return w;
}

/* Send address+PDU raw (libmodbus adds the CRC) and return the response length. */
static int raw_exchange(const uint8_t *req, int len, uint8_t *rsp)
{
    assert_true(modbus_send_raw_request(ctx, req, len) > 0);
    return modbus_receive_confirmation(ctx, rsp);
}

/* Requests expected to get no reply wait a short time only. */
static void expect_silence(bool on)
{
    if (on) {
        modbus_set_response_timeout(ctx, 0, SILENCE_TIMEOUT_US);
    } else {
        modbus_set_response_timeout(ctx, RESPONSE_TIMEOUT_S, 0);
    }
}

/* After line noise, the next request is answered. On a loaded host the pty can
 * hand the noise and the request over as one burst (as a line would if the
 * master ignored the gap); then the slave drops both and the retry is answered. */
static uint16_t read_address_after_noise(void)
{
    uint16_t w = 0;
    const int address = spec_named("modbus_address")->address;
    if (modbus_read_registers(ctx, address, 1, &w) != 1) {
        assert_int_equal(modbus_read_registers(ctx, address, 1, &w), 1);
    }
    return w;
}

static void sleep_ms(long ms)
{
    const struct timespec t = {ms / 1000, (ms % 1000) * 1000000};
    nanosleep(&t, NULL);
}

/* ---- reads of each table ---------------------------------------------------- */

static void test_holding_registers_read_their_defaults(void **state)
{
    (void)state;
    int checked = 0;
    for (int i = 0; i < spec_count; i++) {
        const reg_spec *s = &specs[i];
        if (strcmp(s->table, "holding") != 0 || !s->has_default) {
            continue;
        }
        assert_int_equal(read_holding(s->name), s->def);
        checked++;
    }
    assert_true(checked >= 20);
    /* one long read across the settings block too (FC 03, 25 registers) */
    uint16_t block[25];
    assert_int_equal(modbus_read_registers(ctx, 0, 25, block), 25);
    assert_int_equal(block[spec_named("modbus_address")->address], SLAVE_ADDRESS);
    assert_int_equal(block[spec_named("modbus_baud_div100")->address], 192);
}

static void test_input_registers_show_the_hal_and_time(void **state)
{
    (void)state;
    const int size = table_size("input");
    uint16_t regs[64];
    assert_int_equal(modbus_read_input_registers(ctx, 0, size, regs), size);
    assert_int_equal(regs[spec_named("raw_height_counts")->address], hal_pty_adc_counts[HAL_ADC_HEIGHT]);
    assert_int_equal(regs[spec_named("raw_p_spring_counts")->address], hal_pty_adc_counts[HAL_ADC_P_SPRING]);
    assert_int_equal(regs[spec_named("raw_p_pipe_counts")->address], hal_pty_adc_counts[HAL_ADC_P_PIPE]);
    assert_int_equal(regs[spec_named("raw_p_acc_counts")->address], hal_pty_adc_counts[HAL_ADC_P_ACC]);
    const int up = spec_named("uptime_ms")->address;
    const uint32_t uptime1 = ((uint32_t)regs[up] << 16) | regs[up + 1];
    sleep_ms(50);
    assert_int_equal(modbus_read_input_registers(ctx, up, 2, &regs[up]), 2);
    const uint32_t uptime2 = ((uint32_t)regs[up] << 16) | regs[up + 1];
    assert_true(uptime2 - uptime1 >= 40u && uptime2 - uptime1 < 5000u);
}

static void test_discrete_inputs_show_the_outputs(void **state)
{
    (void)state;
    const int size = table_size("discrete");
    uint8_t bits[32];
    assert_int_equal(modbus_read_input_bits(ctx, 0, size, bits), size);
    assert_int_equal(bits[spec_named("compressor_on")->address], hal_pty_output(HAL_OUT_COMPRESSOR));
    assert_int_equal(bits[spec_named("spring_valve_open")->address], hal_pty_output(HAL_OUT_SPRING_VALVE));
    assert_int_equal(bits[spec_named("vent_valve_open")->address], hal_pty_output(HAL_OUT_VENT_VALVE));
    assert_int_equal(bits[spec_named("acc_valve_open")->address], hal_pty_output(HAL_OUT_ACC_VALVE));
}

static void test_coils_read(void **state)
{
    (void)state;
    const int size = table_size("coil");
    uint8_t bits[32];
    assert_int_equal(modbus_read_bits(ctx, 0, size, bits), size);
    for (int i = 0; i < size; i++) {
        assert_true(bits[i] == 0 || bits[i] == 1);
    }
}

/* ---- writes ------------------------------------------------------------------ */

static void test_write_single_register_reads_back(void **state) /* FC 06 */
{
    (void)state;
    assert_int_equal(write_holding("stall_window_s", 25), 1);
    assert_int_equal(read_holding("stall_window_s"), 25);
    assert_int_equal(write_holding("stall_window_s", spec_named("stall_window_s")->def), 1);
}

static void test_write_multiple_registers_reads_back(void **state) /* FC 16 */
{
    (void)state;
    const reg_spec *lower = spec_named("band_lower_um");
    const reg_spec *upper = spec_named("band_upper_um");
    assert_int_equal(upper->address, lower->address + 2);
    const uint16_t w[4] = {0x0005, 0xF3E0 /* 390112 */, 0x0006, 0x4190 /* 410000 */};
    assert_int_equal(modbus_write_registers(ctx, lower->address, 4, w), 4);
    assert_int_equal(read_holding("band_lower_um"), 390112);
    assert_int_equal(read_holding("band_upper_um"), 410000);
    /* back to the defaults, upper first so lower < upper holds at every step */
    assert_int_equal(write_holding("band_lower_um", lower->def), 2);
    assert_int_equal(write_holding("band_upper_um", upper->def), 2);
    assert_int_equal(read_holding("band_lower_um"), lower->def);
}

static void test_write_coils_read_back(void **state) /* FC 05, 15 */
{
    (void)state;
    const int vent = spec_named("manual_vent_valve")->address;
    const int first = spec_named("manual_compressor")->address;
    uint8_t bits[8];
    assert_int_equal(modbus_write_bit(ctx, vent, 1), 1);
    assert_int_equal(modbus_read_bits(ctx, vent, 1, bits), 1);
    assert_int_equal(bits[0], 1);
    assert_int_equal(modbus_write_bit(ctx, vent, 0), 1);
    assert_int_equal(modbus_read_bits(ctx, vent, 1, bits), 1);
    assert_int_equal(bits[0], 0);

    const uint8_t pattern[4] = {1, 0, 1, 1};
    assert_int_equal(modbus_write_bits(ctx, first, 4, pattern), 4);
    assert_int_equal(modbus_read_bits(ctx, first, 4, bits), 4);
    assert_memory_equal(bits, pattern, 4);
    const uint8_t off[4] = {0, 0, 0, 0};
    assert_int_equal(modbus_write_bits(ctx, first, 4, off), 4);
}

/* The coil `commission` reads `want` within a second (the slave ticks every 10 ms; a loaded machine may
 * run it late): true when it did. */
static bool commission_coil_becomes(int coil, uint8_t want)
{
    uint8_t bit = (uint8_t)!want;
    for (int i = 0; i < 100 && bit != want; i++) {
        sleep_ms(10);
        assert_int_equal(modbus_read_bits(ctx, coil, 1, &bit), 1);
    }
    return bit == want;
}

/* The commissioning command (coil commission) and its result over the wire: refused under algorithm 1
 * (the default), running under algorithm 3 until the coil is written 0 (aborted); the result is a
 * read-only holding register (kept in flash with the settings). */
static void test_commission_coil_and_result(void **state)
{
    (void)state;
    const int coil = spec_named("commission")->address;
    assert_int_equal(read_holding("algorithm"), 1);
    assert_int_equal(modbus_write_bit(ctx, coil, 1), 1);
    assert_true(commission_coil_becomes(coil, 0)); /* the next tick refuses it */
    assert_int_equal(read_holding("commission_result"), 4 /* refused */);
    errno = 0;
    assert_int_equal(write_holding("commission_result", 0), -1);
    assert_int_equal(errno, EMBXILVAL);

    assert_int_equal(write_holding("algorithm", 3), 1);
    assert_int_equal(modbus_write_bit(ctx, coil, 1), 1);
    sleep_ms(50);
    assert_true(commission_coil_becomes(coil, 1)); /* running: it stays 1 */
    assert_true(read_input("commission_step") >= 1);
    assert_int_equal(modbus_write_bit(ctx, coil, 0), 1);
    for (int i = 0; i < 100 && read_input("commission_step") != 0; i++)
        sleep_ms(10);
    assert_int_equal(read_input("commission_step"), 0);
    assert_int_equal(read_holding("commission_result"), 3 /* aborted */);
    assert_int_equal(write_holding("algorithm", 1), 1);
}

/* ---- exceptions ---------------------------------------------------------------- */

static void test_exception_01_illegal_function(void **state)
{
    (void)state;
    uint8_t id[64];
    errno = 0;
    assert_int_equal(modbus_report_slave_id(ctx, sizeof id, id), -1); /* FC 17 */
    assert_int_equal(errno, EMBXILFUN);
    const uint8_t diag[] = {SLAVE_ADDRESS, 0x08, 0x00, 0x00, 0x12, 0x34}; /* FC 08 */
    uint8_t rsp[MODBUS_RTU_MAX_ADU_LENGTH];
    assert_int_equal(raw_exchange(diag, sizeof diag, rsp), 5);
    assert_int_equal(rsp[1], 0x88);
    assert_int_equal(rsp[2], 0x01);
}

static void test_exception_02_illegal_address_each_table(void **state)
{
    (void)state;
    uint8_t bits[8];
    uint16_t words[8];
    errno = 0;
    assert_int_equal(modbus_read_bits(ctx, table_size("coil"), 1, bits), -1);
    assert_int_equal(errno, EMBXILADD);
    errno = 0;
    assert_int_equal(modbus_read_input_bits(ctx, table_size("discrete") - 1, 2, bits), -1);
    assert_int_equal(errno, EMBXILADD);
    errno = 0;
    assert_int_equal(modbus_read_registers(ctx, table_size("holding"), 1, words), -1);
    assert_int_equal(errno, EMBXILADD);
    errno = 0;
    assert_int_equal(modbus_read_input_registers(ctx, 0xFFFF, 1, words), -1);
    assert_int_equal(errno, EMBXILADD);
    errno = 0;
    assert_int_equal(modbus_write_bit(ctx, table_size("coil"), 1), -1);
    assert_int_equal(errno, EMBXILADD);
    errno = 0;
    assert_int_equal(modbus_write_register(ctx, table_size("holding"), 1), -1);
    assert_int_equal(errno, EMBXILADD);
    const uint8_t on[2] = {1, 1};
    errno = 0;
    assert_int_equal(modbus_write_bits(ctx, table_size("coil") - 1, 2, on), -1);
    assert_int_equal(errno, EMBXILADD);
    errno = 0;
    assert_int_equal(modbus_write_registers(ctx, table_size("holding") - 1, 2, words), -1);
    assert_int_equal(errno, EMBXILADD);
}

static void test_exception_03_quantity_and_structure(void **state)
{
    (void)state;
    uint8_t rsp[MODBUS_RTU_MAX_ADU_LENGTH];
    /* quantity 0 and 126 registers: 03 even at address 0 (quantity is checked first) */
    const uint8_t zero[] = {SLAVE_ADDRESS, 0x03, 0x00, 0x00, 0x00, 0x00};
    assert_int_equal(raw_exchange(zero, sizeof zero, rsp), 5);
    assert_int_equal(rsp[1], 0x83);
    assert_int_equal(rsp[2], 0x03);
    const uint8_t too_many[] = {SLAVE_ADDRESS, 0x04, 0xFF, 0x00, 0x00, 126};
    assert_int_equal(raw_exchange(too_many, sizeof too_many, rsp), 5);
    assert_int_equal(rsp[1], 0x84);
    assert_int_equal(rsp[2], 0x03);
    /* a coil value other than 0xFF00 / 0x0000 */
    const uint8_t bad_coil[] = {SLAVE_ADDRESS, 0x05, 0x00, 0x01, 0x12, 0x34};
    assert_int_equal(raw_exchange(bad_coil, sizeof bad_coil, rsp), 5);
    assert_int_equal(rsp[1], 0x85);
    assert_int_equal(rsp[2], 0x03);
    /* FC 16 whose byte count disagrees with the quantity */
    const uint8_t bad_count[] = {SLAVE_ADDRESS, 0x10, 0x00, 0x00, 0x00, 0x01, 0x04, 0x00, 0x01, 0x00, 0x01};
    assert_int_equal(raw_exchange(bad_count, sizeof bad_count, rsp), 5);
    assert_int_equal(rsp[1], 0x90);
    assert_int_equal(rsp[2], 0x03);
}

static void test_exception_03_refused_write_changes_nothing(void **state)
{
    (void)state;
    const long long lower = read_holding("band_lower_um");
    const long long upper = read_holding("band_upper_um");
    /* lower edge at the upper one: the register map refuses (band order) */
    const uint32_t u = (uint32_t)upper;
    const uint16_t w[4] = {(uint16_t)(u >> 16), (uint16_t)u, (uint16_t)(u >> 16), (uint16_t)u};
    errno = 0;
    assert_int_equal(modbus_write_registers(ctx, spec_named("band_lower_um")->address, 4, w), -1);
    assert_int_equal(errno, EMBXILVAL);
    assert_int_equal(read_holding("band_lower_um"), lower);
    assert_int_equal(read_holding("band_upper_um"), upper);
    assert_int_equal(read_input("last_refusal_reason"), 3 /* band order, regmap.h */);

    /* a value outside the field's range through FC 06 */
    const long long mode = read_holding("mode");
    errno = 0;
    assert_int_equal(write_holding("mode", 7), -1);
    assert_int_equal(errno, EMBXILVAL);
    assert_int_equal(read_holding("mode"), mode);
}

/* Exception 04 cannot be provoked over the wire with this register map: see
 * test_modbus_handle.c, which reaches it through leveler_modbus_rtu_handle(). */

/* ---- addressing ------------------------------------------------------------------ */

static void test_broadcast_write_takes_effect_without_reply(void **state)
{
    (void)state;
    modbus_set_slave(ctx, MODBUS_BROADCAST_ADDRESS);
    expect_silence(true);
    errno = 0;
    const int rc = write_holding("stall_window_s", 33);
    expect_silence(false);
    modbus_set_slave(ctx, SLAVE_ADDRESS);
    assert_int_equal(rc, -1); /* libmodbus 3.1.6 waits for a reply that must not come */
    assert_int_equal(errno, ETIMEDOUT);
    assert_int_equal(read_holding("stall_window_s"), 33);
    assert_int_equal(write_holding("stall_window_s", spec_named("stall_window_s")->def), 1);
}

static void test_other_address_is_ignored(void **state)
{
    (void)state;
    modbus_set_slave(ctx, 7);
    expect_silence(true);
    uint16_t w;
    errno = 0;
    const int rc = modbus_read_registers(ctx, 0, 1, &w);
    const int err = errno;
    errno = 0;
    const int wrc = modbus_write_register(ctx, spec_named("stall_window_s")->address, 44);
    expect_silence(false);
    modbus_set_slave(ctx, SLAVE_ADDRESS);
    assert_int_equal(rc, -1);
    assert_int_equal(err, ETIMEDOUT);
    assert_int_equal(wrc, -1);
    assert_int_equal(read_holding("stall_window_s"), spec_named("stall_window_s")->def);
}

static void test_new_slave_address_takes_over(void **state)
{
    (void)state;
    assert_int_equal(write_holding("modbus_address", 9), 1); /* answered from address 1 */
    uint16_t w;
    expect_silence(true);
    errno = 0;
    const int rc = modbus_read_registers(ctx, 0, 1, &w);
    const int err = errno;
    expect_silence(false);
    assert_int_equal(rc, -1);
    assert_int_equal(err, ETIMEDOUT);
    modbus_set_slave(ctx, 9);
    assert_int_equal(read_holding("modbus_address"), 9);
    assert_int_equal(write_holding("modbus_address", SLAVE_ADDRESS), 1);
    modbus_set_slave(ctx, SLAVE_ADDRESS);
    assert_int_equal(read_holding("modbus_address"), SLAVE_ADDRESS);
}

/* ---- malformed byte streams: the next good request is still answered ------------- */

static void test_garbage_frames_are_dropped(void **state)
{
    (void)state;
    const int fd = modbus_get_socket(ctx);
    /* a few bytes of noise, then silence */
    const uint8_t noise[] = {0x01, 0x03, 0x00};
    assert_int_equal(write(fd, noise, sizeof noise), (ssize_t)sizeof noise);
    sleep_ms(50);
    assert_int_equal(read_address_after_noise(), SLAVE_ADDRESS);

    /* an oversized frame (> 256 bytes) addressed to us */
    uint8_t big[400];
    memset(big, 0x01, sizeof big);
    assert_int_equal(write(fd, big, sizeof big), (ssize_t)sizeof big);
    sleep_ms(50);
    assert_int_equal(read_address_after_noise(), SLAVE_ADDRESS);

    /* a write to stall_window_s with a corrupted CRC: ignored */
    const reg_spec *s = spec_named("stall_window_s");
    const uint8_t bad_crc[] = {SLAVE_ADDRESS, 0x06, 0x00, (uint8_t)s->address, 0x00, 50, 0xDE, 0xAD};
    assert_int_equal(write(fd, bad_crc, sizeof bad_crc), (ssize_t)sizeof bad_crc);
    sleep_ms(SILENCE_TIMEOUT_US / 1000);
    uint8_t junk[64];
    assert_true(read(fd, junk, sizeof junk) <= 0); /* no reply */
    assert_int_equal(read_holding("stall_window_s"), s->def);
}

int main(int argc, char **argv)
{
    load_register_map(argc > 1 ? argv[1] : LEVELER_REGISTERS_JSON);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_holding_registers_read_their_defaults),
        cmocka_unit_test(test_input_registers_show_the_hal_and_time),
        cmocka_unit_test(test_discrete_inputs_show_the_outputs),
        cmocka_unit_test(test_coils_read),
        cmocka_unit_test(test_commission_coil_and_result),
        cmocka_unit_test(test_write_single_register_reads_back),
        cmocka_unit_test(test_write_multiple_registers_reads_back),
        cmocka_unit_test(test_write_coils_read_back),
        cmocka_unit_test(test_exception_01_illegal_function),
        cmocka_unit_test(test_exception_02_illegal_address_each_table),
        cmocka_unit_test(test_exception_03_quantity_and_structure),
        cmocka_unit_test(test_exception_03_refused_write_changes_nothing),
        cmocka_unit_test(test_broadcast_write_takes_effect_without_reply),
        cmocka_unit_test(test_other_address_is_ignored),
        cmocka_unit_test(test_new_slave_address_takes_over),
        cmocka_unit_test(test_garbage_frames_are_dropped),
    };
    return cmocka_run_group_tests(tests, start_slave_and_master, stop_slave_and_master);
}
