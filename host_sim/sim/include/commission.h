/*
 * What a commissioning engineer writes into the firmware before a run, through
 * the register map (so the same validation applies as for a SCADA write):
 * the transducer calibration of the config's sensor spans, the band, the
 * algorithm and the accumulator charge.
 * Used by leveler-sim and by the diagnosis library, so both run the firmware
 * set up the same way.
 */
#ifndef LEVELER_SIM_COMMISSION_H
#define LEVELER_SIM_COMMISSION_H

#include <stdbool.h>
#include <stddef.h>

#include "leveler/hal.h"
#include "plant.h"

/* 0, or -1 with "firmware refused <what> (holding a..b, reason r)" in err. */
int sim_commission(const plant_config *cfg, int algorithm, char *err, size_t len);

#endif /* LEVELER_SIM_COMMISSION_H */
