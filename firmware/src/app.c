#include "leveler/app.h"

#include <string.h>

#include "internal.h"
#include "leveler/alg3.h"
#include "leveler/commissioning.h"
#include "leveler/control.h"
#include "leveler/hal.h"
#include "leveler/sensors.h"
#include "leveler/settings.h"
#include "leveler/status.h"
#include "leveler/supervisor.h"

static leveler_sensors g_sensors;
static leveler_supervisor g_supervisor;
static leveler_alg3 g_alg3;
static leveler_commission g_commission;
static leveler_status g_status;
static leveler_command g_command;
static uint32_t g_start_ms;
static uint32_t g_last_tick_ms;
static bool g_ticked;

const leveler_status *leveler_app_status(void)
{
    return &g_status;
}

const leveler_command *leveler_app_command(void)
{
    return &g_command;
}

leveler_command *leveler_app_command_mut(void)
{
    return &g_command;
}

void leveler_app_clear_faults(void)
{
    leveler_supervisor_clear(&g_supervisor);
    g_status.latched_fault_bits = g_supervisor.latched_bits;
    g_status.fault_latched = false;
}

void leveler_app_note_refusal(uint16_t reason)
{
    g_status.last_refusal_reason = reason;
}

static void drive(const leveler_outputs *o, bool led)
{
    hal_output_set(HAL_OUT_COMPRESSOR, o->compressor);
    hal_output_set(HAL_OUT_SPRING_VALVE, o->spring_valve);
    hal_output_set(HAL_OUT_VENT_VALVE, o->vent_valve);
    hal_output_set(HAL_OUT_ACC_VALVE, o->acc_valve);
    hal_output_set(HAL_OUT_STATUS_LED, led);
}

/* LED: steady on when running normally, 1 Hz blink while waiting for valid
 * sensors or in mode off, 4 Hz blink while a fault is latched. */
static bool led_pattern(uint32_t uptime_ms)
{
    if (g_status.fault_latched) {
        return ((uptime_ms / 125u) & 1u) == 0u;
    }
    if (g_status.outputs_safe) {
        return ((uptime_ms / 500u) & 1u) == 0u;
    }
    return true;
}

void leveler_app_init(void)
{
    static const leveler_outputs safe = {false, false, false, false};
    drive(&safe, false); /* first thing: safe outputs */
    leveler_settings_reset();
    g_start_ms = hal_now_ms();
    g_last_tick_ms = g_start_ms;
    g_ticked = false;
    leveler_sensors_init(&g_sensors, g_start_ms);
    leveler_supervisor_init(&g_supervisor);
    leveler_alg3_init(&g_alg3, g_start_ms);
    leveler_commission_init(&g_commission);
    memset(&g_command, 0, sizeof(g_command));
    /* hardware facts the board may report before init */
    bool clock_fault = g_status.clock_fault;
    bool watchdog_reset = g_status.watchdog_reset;
    memset(&g_status, 0, sizeof(g_status));
    g_status.clock_fault = clock_fault;
    g_status.watchdog_reset = watchdog_reset;
    g_status.firmware_version = LEVELER_FIRMWARE_VERSION;
    g_status.control_state = LEVELER_STATE_SAFE;
    g_status.outputs_safe = true;
}

/* Algorithm 3 keeps state between ticks and learns into the settings. */
static leveler_control_state alg3_decide(const leveler_settings *set, const leveler_measurements *m, uint32_t now_ms,
                                         leveler_outputs *request)
{
    static leveler_settings learnt;
    bool changed = false;
    bool held = g_supervisor.outputs_safe || set->mode != (uint16_t)LEVELER_MODE_AUTO;
    leveler_control_state band = leveler_alg3_step(&g_alg3, set, m->height_um, m->p_spring_pa, m->p_pipe_pa,
                                                   m->p_acc_pa, now_ms, held, request, &learnt, &changed);
    if (changed) {
        (void)leveler_settings_apply(&learnt); /* validated; a refused value leaves the old one */
    }
    return band;
}

/* The commissioning routine's tick; a latched fault holding the safe state ends it. */
static void commission_tick(const leveler_settings *set, uint32_t now_ms)
{
    bool held_by_fault = g_supervisor.outputs_safe && (g_supervisor.latched_bits & LEVELER_FAULTS_HOLDING_SAFE) != 0u;
    leveler_commission_tick(&g_commission, &g_alg3, set, &g_command, held_by_fault, now_ms);
}

void leveler_app_tick(void)
{
    const leveler_settings *set = leveler_settings_current();
    uint32_t now_ms = hal_now_ms();
    uint32_t dt_ms = g_ticked ? now_ms - g_last_tick_ms : 0u;
    g_last_tick_ms = now_ms;
    g_ticked = true;

    /* 1. sample */
    leveler_sensors_sample(&g_sensors, set, now_ms);
    uint16_t used = leveler_control_channels_used(set->algorithm, set->alg3_accumulator != 0u);
    leveler_measurements m = {
        .height_um = g_sensors.ch[HAL_ADC_HEIGHT].value,
        .p_spring_pa = g_sensors.ch[HAL_ADC_P_SPRING].value,
        .p_pipe_pa = g_sensors.ch[HAL_ADC_P_PIPE].value,
        .p_acc_pa = g_sensors.ch[HAL_ADC_P_ACC].value,
        .sensors_valid = leveler_sensors_valid(&g_sensors, used),
        .sensor_fault_bits = (uint16_t)(leveler_sensors_fault_bits(&g_sensors) & used),
        .channels_used = used,
    };

    /* 2. commissioning (it drives algorithm 3), control (auto) or manual request, then the supervisor's word */
    commission_tick(set, now_ms);
    leveler_outputs request;
    leveler_control_state band =
        (set->algorithm == (uint16_t)LEVELER_ALGO_HYSTERESIS_AWARE)
            ? alg3_decide(set, &m, now_ms, &request)
            : leveler_control_decide(set->algorithm, set->band_lower_um, set->band_upper_um, set->acc_charge_max_pa,
                                     m.height_um, m.p_pipe_pa, m.p_acc_pa, &request);
    if (set->mode == (uint16_t)LEVELER_MODE_MANUAL) {
        request.compressor = g_command.manual_compressor;
        request.spring_valve = g_command.manual_spring_valve;
        request.vent_valve = g_command.manual_vent_valve;
        request.acc_valve = g_command.manual_acc_valve;
    }
    leveler_outputs out;
    leveler_supervisor_step(&g_supervisor, set, set->mode, &m, &request, now_ms, dt_ms, &out);
    leveler_alg3_driven(&g_alg3, &out, now_ms);

    /* 3. publish, then actuate every output */
    g_status.height_um = m.height_um;
    g_status.p_spring_pa = m.p_spring_pa;
    g_status.p_pipe_pa = m.p_pipe_pa;
    g_status.p_acc_pa = m.p_acc_pa;
    g_status.sensor_fault_bits = leveler_sensors_fault_bits(&g_sensors); /* all channels, used or not */
    g_status.sensors_valid = m.sensors_valid;
    for (unsigned c = 0; c < HAL_ADC_COUNT; c++) {
        g_status.raw_counts[c] = g_sensors.ch[c].raw_counts;
    }
    g_status.outputs_safe = g_supervisor.outputs_safe;
    g_status.control_state = (uint16_t)(g_supervisor.outputs_safe ? LEVELER_STATE_SAFE : band);
    g_status.active_fault_bits = g_supervisor.active_bits;
    g_status.latched_fault_bits = g_supervisor.latched_bits;
    g_status.fault_latched = g_supervisor.latched_bits != 0u;
    g_status.last_fault_code = g_supervisor.last_fault_code;
    memcpy(g_status.fault_count, g_supervisor.fault_count, sizeof(g_status.fault_count));
    g_status.compressor_run_ms = g_supervisor.compressor_run_ms;
    g_status.cooldown_left_ms = g_supervisor.cooldown_left_ms;
    g_status.uptime_ms = now_ms - g_start_ms;
    g_status.alg3_phase = g_alg3.phase;
    g_status.alg3_moves = g_alg3.moves;
    g_status.commission_step = g_commission.step;
    g_status.compressor_on = out.compressor;
    g_status.spring_valve_open = out.spring_valve;
    g_status.vent_valve_open = out.vent_valve;
    g_status.acc_valve_open = out.acc_valve;

    drive(&out, led_pattern(g_status.uptime_ms));
}

void leveler_app_report_tick_overrun(void)
{
    if (g_status.tick_overruns != UINT32_MAX) {
        g_status.tick_overruns++;
    }
}

void leveler_app_report_tick_cycles(uint32_t cycles)
{
    if (cycles > g_status.tick_cycles_worst) {
        g_status.tick_cycles_worst = cycles;
    }
}

void leveler_app_report_log(bool fault, uint32_t rows_dropped)
{
    g_status.log_fault = fault;
    g_status.log_rows_dropped = rows_dropped;
}

void leveler_app_report_sensor_scans_failed(uint32_t failed)
{
    g_status.sensor_scans_failed = failed;
}

void leveler_app_report_link_faults_auto_cleared(uint32_t count)
{
    g_status.link_faults_auto_cleared = count;
}

void leveler_app_report_clock_fault(bool hse_failed)
{
    g_status.clock_fault = hse_failed;
}

void leveler_app_report_reset_cause(bool watchdog)
{
    g_status.watchdog_reset = watchdog;
}
