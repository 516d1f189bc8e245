/* Replays every file of the committed corpus through the fuzz harness with a
 * plain main() (no libFuzzer), so gcc + ASan/UBSan runs it in `make test`. */
#define _DEFAULT_SOURCE
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rtu_harness.h"

static int by_name(const struct dirent **a, const struct dirent **b)
{
    return strcmp((*a)->d_name, (*b)->d_name);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: %s CORPUS_DIR\n", argv[0]);
        return 2;
    }
    struct dirent **names;
    const int n = scandir(argv[1], &names, NULL, by_name);
    if (n < 0) {
        perror(argv[1]);
        return 2;
    }
    int replayed = 0;
    for (int i = 0; i < n; i++) {
        if (names[i]->d_name[0] != '.') {
            char path[4096];
            snprintf(path, sizeof path, "%s/%s", argv[1], names[i]->d_name);
            FILE *f = fopen(path, "rb");
            if (f == NULL) {
                perror(path);
                return 1;
            }
            static unsigned char data[4096];
            const size_t len = fread(data, 1, sizeof data, f);
            fclose(f);
            rtu_harness_run(data, len);
            replayed++;
        }
        free(names[i]);
    }
    free(names);
    if (replayed == 0) {
        fprintf(stderr, "%s: empty corpus\n", argv[1]);
        return 1;
    }
    printf("replayed %d corpus inputs: no crash, invariants held\n", replayed);
    return 0;
}
