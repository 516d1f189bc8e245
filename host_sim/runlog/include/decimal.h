/*
 * Decimal text of doubles for the run log, byte for byte what printf's
 * "%.9g" and "%.6f" write (glibc: exact value, rounded half to even), without
 * printf's cost (about 0.2 us a number; a 55 s run logs 55,000 of them).
 * Values of the usual magnitudes take an exact integer path; anything else
 * (very large or small, inf/nan) is handed to snprintf.
 */
#ifndef LEVELER_DECIMAL_H
#define LEVELER_DECIMAL_H

#include <stddef.h>

#define DECIMAL_MAX 40 /* room for any result, terminating 0 included */

/* snprintf(out, DECIMAL_MAX, "%.9g", v); returns the length. */
size_t decimal_g9(double v, char out[DECIMAL_MAX]);
/* snprintf(out, DECIMAL_MAX, "%.6f", v) for |v| < 1e12 (else "%.6g"); returns the length. */
size_t decimal_f6(double v, char out[DECIMAL_MAX]);

#endif /* LEVELER_DECIMAL_H */
