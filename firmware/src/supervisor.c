#include "leveler/supervisor.h"

#include <string.h>

#include "leveler/fixed_point.h"

void leveler_supervisor_init(leveler_supervisor *sv)
{
    memset(sv, 0, sizeof(*sv));
    sv->outputs_safe = true;
}

void leveler_supervisor_clear(leveler_supervisor *sv)
{
    sv->latched_bits = 0;
}

static int32_t max3(int32_t a, int32_t b, int32_t c)
{
    int32_t m = (a > b) ? a : b;
    return (m > c) ? m : c;
}

static unsigned counter_slot(unsigned code)
{
    if (code == (unsigned)LEVELER_FAULT_CHATTER) {
        return 4u;
    }
    return (code >= (unsigned)LEVELER_FAULT_SENSOR_HEIGHT) ? 3u : code - 1u;
}

/* Latch and count the conditions that appeared this tick. */
static void latch(leveler_supervisor *sv, uint16_t active_now)
{
    uint16_t rising = (uint16_t)(active_now & (uint16_t)~sv->active_bits);
    for (unsigned code = 1; code <= (unsigned)LEVELER_FAULT_CHATTER; code++) {
        if ((rising & LEVELER_FAULT_BIT(code)) != 0u) {
            unsigned slot = counter_slot(code);
            sv->fault_count[slot] = leveler_sat_inc_u16(sv->fault_count[slot]);
            sv->last_fault_code = (uint16_t)code;
        }
    }
    sv->active_bits = active_now;
    sv->latched_bits = (uint16_t)(sv->latched_bits | active_now);
}

/* Progress of a fill: any of P1, P2, height rose enough since the reference. */
static bool fill_progressed(const leveler_supervisor *sv, const leveler_settings *set,
                            const leveler_measurements *m)
{
    /* int64: differences of two int32 cannot overflow there. */
    return ((int64_t)m->p_pipe_pa - sv->stall_ref_p_pipe_pa >= set->stall_min_rise_pa) ||
           ((int64_t)m->p_spring_pa - sv->stall_ref_p_spring_pa >= set->stall_min_rise_pa) ||
           ((int64_t)m->height_um - sv->stall_ref_height_um >= set->stall_min_rise_um);
}

static void stall_arm(leveler_supervisor *sv, const leveler_measurements *m, uint32_t now_ms)
{
    sv->stall_armed = true;
    sv->stall_start_ms = now_ms;
    sv->stall_ref_p_pipe_pa = m->p_pipe_pa;
    sv->stall_ref_p_spring_pa = m->p_spring_pa;
    sv->stall_ref_height_um = m->height_um;
}

/* Rule 5: count this tick's driven outputs; true above the set rate. */
static bool chatter_exceeded(leveler_supervisor *sv, const leveler_settings *set, const leveler_outputs *out,
                             uint32_t now_ms)
{
    uint16_t count = leveler_chatter_step(&sv->chatter, leveler_outputs_bits(out), now_ms);
    return set->chatter_max_per_min != 0u && count > set->chatter_max_per_min;
}

void leveler_supervisor_step(leveler_supervisor *sv, const leveler_settings *set, uint16_t mode,
                             const leveler_measurements *m, const leveler_outputs *request, uint32_t now_ms,
                             uint32_t dt_ms, leveler_outputs *out)
{
    uint16_t active = 0;
    for (unsigned c = 0; c < HAL_ADC_COUNT; c++) {
        if ((m->sensor_fault_bits & (1u << c)) != 0u) {
            active = (uint16_t)(active | LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_HEIGHT + c));
        }
    }

    /* Pressure limits act only on trusted readings; untrusted ones mean the safe state anyway. */
    if (m->sensors_valid) {
        /* An unused P3 channel may be unwired: its reading is no evidence. */
        int32_t p_acc_pa = (m->channels_used & (1u << HAL_ADC_P_ACC)) != 0u ? m->p_acc_pa : m->p_pipe_pa;
        int32_t p_max = max3(m->p_pipe_pa, m->p_spring_pa, p_acc_pa);
        if (p_max > set->overpressure_limit_pa) {
            sv->overpressure_cut = true;
        } else if ((int64_t)p_max < (int64_t)set->overpressure_limit_pa - LEVELER_OVERPRESSURE_HYST_PA) {
            sv->overpressure_cut = false;
        }
    }
    if (sv->overpressure_cut) {
        active = (uint16_t)(active | LEVELER_FAULT_BIT(LEVELER_FAULT_OVERPRESSURE));
    }

    sv->cooldown_left_ms = leveler_sat_sub_u32(sv->cooldown_left_ms, dt_ms);

    bool safe = (mode == (uint16_t)LEVELER_MODE_OFF) || !m->sensors_valid ||
                ((sv->latched_bits & LEVELER_FAULTS_HOLDING_SAFE) != 0u) ||
                ((active & LEVELER_FAULTS_HOLDING_SAFE) != 0u);
    if (safe) {
        memset(out, 0, sizeof(*out));
    } else {
        *out = *request;
        if (sv->overpressure_cut || sv->cooldown_left_ms > 0u) {
            out->compressor = false;
        }
        if (m->p_pipe_pa > set->overpressure_vent_pa) {
            out->vent_valve = true;
        }
        if (m->p_spring_pa > set->overpressure_vent_pa) {
            out->vent_valve = true;
            out->spring_valve = true;
        }
        if (m->p_acc_pa > set->overpressure_vent_pa) {
            out->vent_valve = true;
            out->acc_valve = true;
        }
    }

    /* Run-time limit, on the compressor as it would be driven. */
    if (out->compressor) {
        sv->compressor_run_ms = leveler_sat_add_u32(sv->compressor_run_ms, dt_ms);
        if (sv->compressor_run_ms >= (uint32_t)set->compressor_max_run_s * 1000u) {
            out->compressor = false;
            sv->cooldown_left_ms = (uint32_t)set->compressor_cooldown_s * 1000u;
            active = (uint16_t)(active | LEVELER_FAULT_BIT(LEVELER_FAULT_RUN_TIME));
        }
    }
    if (!out->compressor) {
        sv->compressor_run_ms = 0;
    }
    if (sv->cooldown_left_ms > 0u) {
        active = (uint16_t)(active | LEVELER_FAULT_BIT(LEVELER_FAULT_RUN_TIME));
    }

    /* Stall / leak: filling the spring (compressor on, spring valve open) must show
     * progress within the window. Charging only the accumulator in band is not
     * filling: through the diaphragm's knee (106.7..112.7 psia) P3 rises far
     * slower than any sensible threshold, and the run-time limit covers it. */
    if (out->compressor && out->spring_valve) {
        if (!sv->stall_armed || fill_progressed(sv, set, m)) {
            stall_arm(sv, m, now_ms);
        } else if (now_ms - sv->stall_start_ms >= (uint32_t)set->stall_window_s * 1000u) {
            active = (uint16_t)(active | LEVELER_FAULT_BIT(LEVELER_FAULT_STALL));
            memset(out, 0, sizeof(*out));
            safe = true;
            sv->stall_armed = false;
            sv->compressor_run_ms = 0;
        }
    } else {
        sv->stall_armed = false;
    }

    if (chatter_exceeded(sv, set, out, now_ms)) {
        active = (uint16_t)(active | LEVELER_FAULT_BIT(LEVELER_FAULT_CHATTER));
        memset(out, 0, sizeof(*out));
        safe = true;
    }

    latch(sv, active);
    sv->outputs_safe = safe;
}
