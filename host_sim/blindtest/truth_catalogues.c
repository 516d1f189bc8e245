/*
 * The engine's effect tables in the blind test's build (libleveler_truth.so):
 * the candidates, the first truth family (truth.c, truth.json) and the second,
 * written from the physics alone (truth2.c, truth2.json). In place of the
 * product's host_sim/diagnose/engine_catalogues.c (link-time substitution):
 * the truths stay out of the product's library.
 */
#include "engine.h"

extern const plant_fx_model truth_catalogue[];
extern const int truth_catalogue_count;
extern const plant_fx_model truth2_catalogue[];
extern const int truth2_catalogue_count;

int engine_catalogue_find(int which, engine_catalogue *out)
{
    switch (which) {
    case ENGINE_CANDIDATES:
        *out = (engine_catalogue){plant_fx_catalogue, plant_fx_catalogue_count};
        return 0;
    case ENGINE_TRUTH:
        *out = (engine_catalogue){truth_catalogue, truth_catalogue_count};
        return 0;
    case ENGINE_TRUTH2:
        *out = (engine_catalogue){truth2_catalogue, truth2_catalogue_count};
        return 0;
    default:
        return -1;
    }
}
