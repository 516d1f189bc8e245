/*
 * The physical checks of a plant config (plant.h: plant_config_check): what no
 * single key can say alone -- edges in order, spans not empty, the diaphragm
 * curve positive and continuous, the effective area physical.
 */
#include "plant.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>

static int cfail(char *err, size_t len, const plant_config *c, const char *fmt, ...)
{
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    snprintf(err, len, "%s: %s", c->path[0] ? c->path : "(config)", msg);
    return -1;
}

/* Edges in order, bands given, sensor spans not empty. */
static int check_edges(const plant_config *c, char *err, size_t len)
{
    const plant_params *p = &c->plant;
    if (c->band_lower_m >= c->band_upper_m)
        return cfail(err, len, c, "[controller] band_lower must be below band_upper");
    if (p->height_min_m >= p->height_max_m)
        return cfail(err, len, c, "[platform] height_min must be below height_max");
    if (p->init_height_m < p->height_min_m || p->init_height_m > p->height_max_m)
        return cfail(err, len, c, "[initial] height outside [platform] height_min..height_max");
    if (p->band_count < 1)
        return cfail(err, len, c, "at least one [hysteresis.N] band is required");
    for (int i = 0; i < p->band_count; i++) {
        const plant_hysteresis_band *b = &p->bands[i];
        if (b->load_below_n <= 0)
            return cfail(err, len, c, "[hysteresis.%d] needs load_below, up_slope, up_intercept, down_offset", i + 1);
    }
    if (c->sensors.height_lo_counts == c->sensors.height_hi_counts || c->sensors.height_lo_m == c->sensors.height_hi_m)
        return cfail(err, len, c, "[sensors] height span is empty");
    if (c->sensors.pressure_lo_counts == c->sensors.pressure_hi_counts ||
        c->sensors.pressure_lo_pa == c->sensors.pressure_hi_pa)
        return cfail(err, len, c, "[sensors] pressure span is empty");
    return 0;
}

/* One slope and intercept per segment; V positive and continuous over the segments. */
static int check_diaphragm(const plant_config *c, char *err, size_t len)
{
    const plant_params *p = &c->plant;
    if (p->diaphragm_slope_count != p->diaphragm_segments || p->diaphragm_intercept_count != p->diaphragm_segments)
        return cfail(err, len, c,
                     "[accumulator] diaphragm_breaks_psia gives %d segments, but diaphragm_slopes_in3_per_psi has %d "
                     "and diaphragm_intercepts_in3 %d values (one per segment)",
                     p->diaphragm_segments, p->diaphragm_slope_count, p->diaphragm_intercept_count);
    for (int i = 0; i < p->diaphragm_segments; i++) {
        /* V must stay positive over the segment and join its neighbour (air in the
         * accumulator is P3 V: a jump in V would create or destroy air) */
        double lo = i == 0 ? p->ambient_pa * 0.5 : p->diaphragm_break_pa[i - 1];
        double hi = i == p->diaphragm_segments - 1 ? 2e6 : p->diaphragm_break_pa[i];
        double v_lo = p->diaphragm_slope_m3_per_pa[i] * lo + p->diaphragm_intercept_m3[i];
        double v_hi = p->diaphragm_slope_m3_per_pa[i] * hi + p->diaphragm_intercept_m3[i];
        if (!(v_lo > 1e-7 && v_hi > 1e-7))
            return cfail(err, len, c, "[accumulator] diaphragm segment %d: volume %.4g in^3 at %.4g psia (must stay > 0)",
                         i + 1, fmin(v_lo, v_hi) / pow(PLANT_M_PER_IN, 3), (v_lo < v_hi ? lo : hi) / PLANT_PA_PER_PSI);
        if (i + 1 < p->diaphragm_segments) {
            double v_next = p->diaphragm_slope_m3_per_pa[i + 1] * hi + p->diaphragm_intercept_m3[i + 1];
            if (fabs(v_next - v_hi) > 1e-3 * fmax(v_hi, v_next))
                return cfail(err, len, c,
                             "[accumulator] diaphragm segments %d and %d meet at %.6g psia with %.6g and %.6g in^3 "
                             "(must join within 0.1 %%)",
                             i + 1, i + 2, hi / PLANT_PA_PER_PSI, v_hi / pow(PLANT_M_PER_IN, 3),
                             v_next / pow(PLANT_M_PER_IN, 3));
        }
    }
    return 0;
}

/* The effective area must stay physical over the range the fit was made for
 * (the thesis fit is negative at no load). */
static int check_area(const plant_config *c, char *err, size_t len)
{
    const plant_params *p = &c->plant;
    for (double load_lbf = 700.0; load_lbf <= 1500.0; load_lbf += 50.0)
        for (double y_in = 10.0; y_in <= 20.0; y_in += 1.0) {
            double a_in2 = plant_effective_area_m2(p, load_lbf * PLANT_N_PER_LBF, y_in * PLANT_M_PER_IN) /
                           (PLANT_M_PER_IN * PLANT_M_PER_IN);
            if (!(a_in2 >= 1.0 && a_in2 <= 1000.0))
                return cfail(err, len, c,
                             "[spring] area_cc1_poly_in2/area_cc2_poly_in2_per_in give %.4g in^2 at %g lbf, %g in "
                             "(allowed 1..1000 in^2 for 700..1500 lbf, 10..20 in)",
                             a_in2, load_lbf, y_in);
        }
    return 0;
}

int plant_config_check(const plant_config *c, char *err, size_t len)
{
    if (check_edges(c, err, len) != 0 || check_diaphragm(c, err, len) != 0)
        return -1;
    if (c->step_on_s > c->step_off_s)
        return cfail(err, len, c, "[scenario] step_on must not be after step_off");
    if (c->valid_load_min_n >= c->valid_load_max_n)
        return cfail(err, len, c, "[spring] load_min must be below load_max");
    return check_area(c, err, len);
}
