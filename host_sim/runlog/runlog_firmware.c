/*
 * The run-log columns the firmware fills (runlog_firmware.h): what it read
 * and the state it is in, from its status after a tick. Shared by
 * leveler-sim and leveler-rig, so both log the same things the same way.
 */
#include "runlog_firmware.h"

#include <math.h>

#include "leveler/settings.h"
#include "leveler/status.h"

void runlog_row_firmware_state(runlog_row *row)
{
    const leveler_status *st = leveler_app_status();
    row->mode = leveler_settings_current()->mode;
    row->control_state = st->control_state;
    row->latched_fault_bits = st->latched_fault_bits;
    row->sensors_valid = st->sensors_valid ? 1 : 0;
}

void runlog_row_firmware_readings(runlog_row *row, int has_acc)
{
    const leveler_status *st = leveler_app_status();
    row->height_m = st->height_um * 1e-6;
    row->p_spring_pa = st->p_spring_pa;
    row->p_pipe_pa = st->p_pipe_pa;
    row->p_acc_pa = has_acc ? st->p_acc_pa : NAN;
}

const char *runlog_fault_name(int code)
{
    /* the codes of registers.json last_fault_code (leveler_fault_code) */
    static const char *const names[] = {"none", "overpressure", "compressor run time", "stall (no rise while charging)",
                                        "height sensor", "P2 sensor", "P1 sensor", "P3 sensor",
                                        "chatter (outputs switching faster than chatter_max_per_min)"};
    return code >= 0 && code < (int)(sizeof names / sizeof names[0]) ? names[code] : "unknown fault";
}
