/* The engine's effect tables in the product's build: the candidates only.
 * The blind test's build links its own list (host_sim/blindtest/truth_catalogues.c). */
#include "engine.h"

int engine_catalogue_find(int which, engine_catalogue *out)
{
    if (which != ENGINE_CANDIDATES)
        return -1;
    *out = (engine_catalogue){plant_fx_catalogue, plant_fx_catalogue_count};
    return 0;
}
