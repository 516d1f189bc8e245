/* libFuzzer target: the RTU frame parser and framing (see rtu_harness.h). */
#include <stddef.h>
#include <stdint.h>

#include "rtu_harness.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    rtu_harness_run(data, size);
    return 0;
}
