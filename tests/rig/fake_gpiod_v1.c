/* A fake of the few libgpiod 1.x calls gpio_gpiod_v1.c makes (link-time
 * substitution): it keeps each line's physical level, request flags and
 * owner so the test can check the backend's effect on the "pins". */
#include "fake_gpiod_v1.h"

#include <errno.h>
#include <string.h>

struct gpiod_chip {
    int index;
    int open;
};
struct gpiod_line {
    fake_line state;
};

static struct gpiod_chip chips[FAKE_CHIPS];
static struct gpiod_line lines[FAKE_CHIPS][FAKE_LINES];

void fake_gpiod_reset(void)
{
    memset(chips, 0, sizeof chips);
    memset(lines, 0, sizeof lines);
    for (int c = 0; c < FAKE_CHIPS; c++)
        for (int l = 0; l < FAKE_LINES; l++)
            lines[c][l].state.physical = -1; /* never driven */
}

const fake_line *fake_gpiod_line(int chip, int line)
{
    return &lines[chip][line].state;
}

int fake_gpiod_open_chips(void)
{
    int n = 0;
    for (int c = 0; c < FAKE_CHIPS; c++)
        n += chips[c].open;
    return n;
}

struct gpiod_chip *gpiod_chip_open_lookup(const char *descr)
{
    /* "gpiochip0", "0" or "/dev/gpiochip0" */
    const char *digits = descr + strcspn(descr, "0123456789");
    if (*digits == '\0' || digits[1] != '\0' || *digits - '0' >= FAKE_CHIPS) {
        errno = ENOENT;
        return NULL;
    }
    struct gpiod_chip *c = &chips[*digits - '0'];
    c->index = *digits - '0';
    c->open++;
    return c;
}

void gpiod_chip_close(struct gpiod_chip *chip)
{
    chip->open--;
}

struct gpiod_line *gpiod_chip_get_line(struct gpiod_chip *chip, unsigned int offset)
{
    if (offset >= FAKE_LINES) {
        errno = EINVAL;
        return NULL;
    }
    return &lines[chip->index][offset];
}

int gpiod_line_request_output_flags(struct gpiod_line *line, const char *consumer, int flags, int default_val)
{
    if (line->state.requested) {
        errno = EBUSY;
        return -1;
    }
    line->state.requested = 1;
    line->state.active_low = (flags & GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW) != 0;
    strncpy(line->state.consumer, consumer, sizeof line->state.consumer - 1);
    line->state.physical = (default_val != 0) ^ line->state.active_low;
    return 0;
}

int gpiod_line_set_value(struct gpiod_line *line, int value)
{
    if (!line->state.requested) {
        errno = EPERM;
        return -1;
    }
    line->state.physical = (value != 0) ^ line->state.active_low;
    line->state.writes++;
    return 0;
}

void gpiod_line_release(struct gpiod_line *line)
{
    line->state.requested = 0;
    line->state.released++;
}
