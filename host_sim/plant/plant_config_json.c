/* The resolved config as JSON (plant.h: plant_config_write_json), from the loader's tables. */
#include "plant.h"
#include "config_table.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>

/* The SI suffix of a unit kind: its entry with factor 1, not gauge; "" for plain numbers. */
static const char *si_suffix(kind k)
{
    for (size_t i = 0; i < config_unit_count; i++)
        if (units[i].k == k && units[i].factor == 1.0 && !units[i].gauge)
            return units[i].suffix;
    return "";
}

static void json_string(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        unsigned char ch = (unsigned char)*s;
        if (ch == '"' || ch == '\\')
            fprintf(f, "\\%c", ch);
        else if (ch < 0x20)
            fprintf(f, "\\u%04x", ch);
        else
            fputc(ch, f);
    }
    fputc('"', f);
}

static void json_field(FILE *f, const field *fd, const char *base, const char *sep)
{
    const char *suffix = si_suffix(fd->k);
    fprintf(f, "%s\"%s%s%s\": ", sep, fd->base, suffix[0] ? "_" : "", suffix);
    const char *v = base + fd->offset;
    if (fd->t == T_DOUBLE)
        fprintf(f, "%.17g", *(const double *)v);
    else if (fd->t == T_INT)
        fprintf(f, "%d", *(const int *)v);
    else
        fprintf(f, "%u", (unsigned)*(const uint32_t *)v);
}

static void json_list(FILE *f, const char *key, const double *v, int n)
{
    fprintf(f, ", \"%s\": [", key);
    for (int i = 0; i < n; i++)
        fprintf(f, "%s%.17g", i ? ", " : "", v[i]);
    fputc(']', f);
}

/* The hysteresis bands with the load range plant_band_for_load() gives each
 * (covers_below_n null: every heavier load). */
static void json_bands(FILE *f, const plant_params *p)
{
    fprintf(f, "  \"hysteresis\": [");
    for (int b = 0; b < p->band_count; b++) {
        const plant_hysteresis_band *band = &p->bands[b];
        double from = 0.0, below = band->load_below_n;
        int last = 1;
        for (int o = 0; o < p->band_count; o++) {
            double other = p->bands[o].load_below_n;
            if (other < band->load_below_n && other > from)
                from = other;
            if (other > band->load_below_n)
                last = 0;
        }
        fprintf(f, "%s\n    {", b ? "," : "");
        int n = 0;
        for (size_t i = 0; i < config_field_count; i++)
            if (strcmp(fields[i].section, "hysteresis") == 0)
                json_field(f, &fields[i], (const char *)band, n++ ? ", " : "");
        fprintf(f, ", \"covers_from_n\": %.17g, \"covers_below_n\": ", from);
        if (last)
            fprintf(f, "null}");
        else
            fprintf(f, "%.17g}", below);
    }
    fprintf(f, "\n  ]");
}

int plant_config_write_json(const plant_config *c, FILE *f)
{
    static const char *const acc_types[] = {"none", "tube", "diaphragm"};
    const plant_params *p = &c->plant;
    fprintf(f, "{\n  \"config\": {\"name\": ");
    json_string(f, c->name);
    fprintf(f, ", \"path\": ");
    json_string(f, c->path);
    fprintf(f, "},\n");
    const char *open = NULL;
    for (size_t i = 0; i < config_field_count; i++) {
        const field *fd = &fields[i];
        if (strcmp(fd->section, "hysteresis") == 0)
            continue;
        int first = !open || strcmp(open, fd->section) != 0;
        if (first) {
            if (open)
                fprintf(f, "},\n");
            fprintf(f, "  \"%s\": {", fd->section);
            open = fd->section;
        }
        json_field(f, fd, (const char *)c, first ? "" : ", ");
        int last = i + 1 == config_field_count || strcmp(fields[i + 1].section, fd->section) != 0;
        if (last && strcmp(fd->section, "accumulator") == 0) { /* the keys read by hand */
            fprintf(f, ", \"type\": \"%s\"", acc_types[p->acc_type]);
            json_list(f, "diaphragm_breaks_pa", p->diaphragm_break_pa, p->diaphragm_segments - 1);
            json_list(f, "diaphragm_slopes_m3_per_pa", p->diaphragm_slope_m3_per_pa, p->diaphragm_segments);
            json_list(f, "diaphragm_intercepts_m3", p->diaphragm_intercept_m3, p->diaphragm_segments);
        }
        if (last && strcmp(fd->section, "spring") == 0) {
            json_list(f, "area_cc1_poly_in2", p->area_cc1_in2, p->area_cc1_terms);
            json_list(f, "area_cc2_poly_in2_per_in", p->area_cc2_in2_per_in, p->area_cc2_terms);
        }
    }
    fprintf(f, "},\n");
    json_bands(f, p);
    fprintf(f, "\n}\n");
    return ferror(f) ? -1 : 0;
}
