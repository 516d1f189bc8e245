/* Exact, printf-identical decimal text of doubles (decimal.h). */
#include "decimal.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

static const uint64_t POW5[21] = {
    1ull, 5ull, 25ull, 125ull, 625ull, 3125ull, 15625ull, 78125ull, 390625ull, 1953125ull, 9765625ull,
    48828125ull, 244140625ull, 1220703125ull, 6103515625ull, 30517578125ull, 152587890625ull,
    762939453125ull, 3814697265625ull, 19073486328125ull, 95367431640625ull};

/* round(|v| * 10^k) with ties to even, exactly (v = mant * 2^e2 is a dyadic
 * rational, so |v| * 10^k = mant * 5^k * 2^(e2 + k) in 128-bit integers).
 * false when k is outside 0..20 or the result does not fit 64 bits. */
static bool scaled_round(double av, int k, uint64_t *out)
{
    if (k < 0 || k > 20)
        return false;
    uint64_t bits;
    memcpy(&bits, &av, sizeof bits);
    int biased = (int)((bits >> 52) & 0x7FFu);
    uint64_t mant = bits & ((1ull << 52) - 1u);
    if (biased == 0x7FF)
        return false; /* inf, nan */
    if (biased)
        mant |= 1ull << 52;
    else
        biased = 1; /* subnormal */
    int e2 = biased - 1075; /* av = mant * 2^e2 */
    unsigned __int128 p = (unsigned __int128)mant * POW5[k]; /* < 2^53 * 5^20 < 2^100 */
    int s = e2 + k;
    if (s >= 0) {
        if (s > 63 || (p >> (64 - s)) != 0)
            return false;
        p <<= s;
    } else if (-s >= 127) {
        p = 0; /* far below one unit: rounds to 0 */
    } else {
        int r = -s;
        unsigned __int128 one = (unsigned __int128)1 << r;
        unsigned __int128 q = p >> r, rem = p & (one - 1), half = one >> 1;
        if (rem > half || (rem == half && (q & 1u)))
            q++;
        p = q;
    }
    if (p >> 64)
        return false;
    *out = (uint64_t)p;
    return true;
}

/* Writes n as decimal with exactly ndig digits (leading zeros kept). */
static void put_digits(char *dst, uint64_t n, int ndig)
{
    for (int i = ndig - 1; i >= 0; i--) {
        dst[i] = (char)('0' + n % 10u);
        n /= 10u;
    }
}

static const uint64_t POW10[] = {1ull, 10ull, 100ull, 1000ull, 10000ull, 100000ull, 1000000ull, 10000000ull,
                                 100000000ull, 1000000000ull};

size_t decimal_g9(double v, char out[DECIMAL_MAX])
{
    if (v == 0.0 && !signbit(v)) {
        memcpy(out, "0", 2);
        return 1;
    }
    double av = fabs(v);
    /* decimal exponent x with 10^x <= av < 10^(x+1) after rounding to 9 digits */
    if (!(av >= 1e-4 && av < 1e8))
        return (size_t)snprintf(out, DECIMAL_MAX, "%.9g", v);
    /* a first guess from a table; the exact rounding below corrects it */
    static const double DEC[] = {1e-4, 1e-3, 1e-2, 1e-1, 1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7};
    int x = -4;
    while (x < 7 && av >= DEC[x + 5])
        x++;
    uint64_t n = 0;
    for (int tries = 0;; tries++) {
        if (tries > 2 || !scaled_round(av, 8 - x, &n))
            return (size_t)snprintf(out, DECIMAL_MAX, "%.9g", v);
        if (n >= POW10[9])
            x++;
        else if (n < POW10[8])
            x--;
        else
            break;
    }
    if (x < -4 || x >= 9)
        return (size_t)snprintf(out, DECIMAL_MAX, "%.9g", v);
    /* %f style with 8 - x decimals, trailing zeros (and a bare point) removed.
     * Digits go straight to their places: copying a few bytes costs more. */
    size_t len = 0;
    if (signbit(v))
        out[len++] = '-';
    char *o = out + len;
    if (x >= 0) {
        for (int i = 8; i >= 0; i--, n /= 10u)
            o[i + (i > x)] = (char)('0' + n % 10u);
        o[x + 1] = '.';
        len += 10;
    } else {
        o[0] = '0';
        o[1] = '.';
        o[2] = o[3] = o[4] = '0'; /* up to three zeros after the point (x >= -4) */
        int first = 2 + (-x - 1);
        for (int i = 8; i >= 0; i--, n /= 10u)
            o[first + i] = (char)('0' + n % 10u);
        len += (size_t)first + 9;
    }
    while (out[len - 1] == '0')
        len--;
    if (out[len - 1] == '.')
        len--;
    out[len] = 0;
    return len;
}

size_t decimal_f6(double v, char out[DECIMAL_MAX])
{
    uint64_t n;
    if (!(fabs(v) < 1e12) || !scaled_round(fabs(v), 6, &n))
        return (size_t)snprintf(out, DECIMAL_MAX, fabs(v) < 1e12 ? "%.6f" : "%.6g", v);
    uint64_t whole = n / POW10[6], frac = n % POW10[6];
    size_t len = 0;
    if (signbit(v))
        out[len++] = '-';
    int w = 1;
    for (uint64_t q = whole; q >= 10u; q /= 10u)
        w++;
    put_digits(out + len, whole, w);
    len += (size_t)w;
    out[len++] = '.';
    put_digits(out + len, frac, 6);
    len += 6;
    out[len] = 0;
    return len;
}
