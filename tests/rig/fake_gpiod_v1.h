#ifndef FAKE_GPIOD_V1_H
#define FAKE_GPIOD_V1_H
#include <gpiod.h>

#define FAKE_CHIPS 2
#define FAKE_LINES 32

typedef struct {
    int requested;
    int active_low;
    int physical; /* level on the pin: 0/1, -1 never driven */
    int writes;
    int released;
    char consumer[32];
} fake_line;

void fake_gpiod_reset(void);
const fake_line *fake_gpiod_line(int chip, int line);
int fake_gpiod_open_chips(void);
#endif
