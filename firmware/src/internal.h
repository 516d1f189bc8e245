/* Links between the firmware's own modules (not a contract for targets). */
#ifndef LEVELER_INTERNAL_H
#define LEVELER_INTERNAL_H

#include <stdint.h>
#include "leveler/status.h"

/* Power-up: factory defaults in force (leveler_app_init). */
void leveler_settings_reset(void);

/* Register-map hooks into the app. */
leveler_command *leveler_app_command_mut(void);
void leveler_app_clear_faults(void);
void leveler_app_note_refusal(uint16_t reason);

#endif /* LEVELER_INTERNAL_H */
