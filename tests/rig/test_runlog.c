/*
 * Run-log writer: the CSV rows of docs/log-format.md, empty cells, rotation by
 * size with fsync, and no torn line when a writer is killed by SIGTERM.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "decimal.h"
#include "leveler/version.h"
#include "runlog.h"

#define HEADER_COLUMNS                                                                                           \
    "t_s,height_m,p_spring_pa,p_pipe_pa,p_acc_pa,load_n,compressor,spring_valve,vent_valve,acc_valve,mode,"        \
    "control_state,latched_fault_bits,sensors_valid,true_height_m,true_p_spring_pa,true_p_pipe_pa,true_p_acc_pa"
#define HEADER_COMMAS 17 /* format 3: 18 columns */

static char dir[256];

static int setup(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/leveler-runlog-XXXXXX");
    return mkdtemp(dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

static char *slurp(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    size_t got = fread(buf, 1, (size_t)n, f);
    fclose(f);
    buf[got] = '\0';
    if (len)
        *len = got;
    return buf;
}

static runlog_row sample_row(double t)
{
    runlog_row r = runlog_row_empty();
    r.t_s = t;
    r.height_m = 0.39751;
    r.p_spring_pa = 613633.5;
    r.p_pipe_pa = 613000.25;
    r.load_n = 4003.4;
    r.compressor = 1;
    r.spring_valve = 0;
    r.vent_valve = 0;
    r.mode = 1;
    r.control_state = 2;
    r.latched_fault_bits = 128;
    r.sensors_valid = 1;
    r.true_height_m = 0.3975;
    return r;
}

/* Every non-comment line after the column header has exactly the header's fields and ends in '\n'. */
static size_t check_complete_lines(const char *text, size_t len)
{
    assert_true(len > 0);
    assert_int_equal(text[len - 1], '\n');
    size_t rows = 0;
    const char *p = text;
    int seen_header = 0;
    while (*p) {
        const char *eol = strchr(p, '\n');
        assert_non_null(eol);
        if (*p != '#') {
            if (!seen_header) {
                assert_memory_equal(p, HEADER_COLUMNS, strlen(HEADER_COLUMNS));
                seen_header = 1;
            } else {
                int commas = 0;
                for (const char *c = p; c < eol; c++)
                    commas += *c == ',';
                assert_int_equal(commas, HEADER_COMMAS);
                rows++;
            }
        }
        p = eol + 1;
    }
    return rows;
}

static void writes_header_and_rows_with_empty_cells(void **state)
{
    (void)state;
    char path[300], err[200];
    snprintf(path, sizeof path, "%s/run.csv", dir);
    runlog_options o = {.path = path, .config_name = "thesis-900lb", .source = "rig"};
    runlog *log = runlog_open(&o, err, sizeof err);
    assert_non_null(log);
    runlog_row r = sample_row(1.25);
    assert_int_equal(runlog_write(log, &r), 0);
    runlog_row empty = runlog_row_empty();
    empty.t_s = 1.26;
    empty.height_m = 0.4;
    empty.load_n = 4003.4;
    assert_int_equal(runlog_write(log, &empty), 0);
    assert_int_equal(runlog_close(log), 0);

    char *text = slurp(path, NULL);
    assert_non_null(text);
    assert_string_equal(text, "# leveler run log, format 3\n# config: thesis-900lb\n# source: rig\n# version: " LEVELER_VERSION
                              "\n" HEADER_COLUMNS "\n"
                              "1.250000,0.39751,613633.5,613000.25,,4003.4,1,0,0,,1,2,128,1,0.3975,,,\n"
                              "1.260000,0.4,,,,4003.4,,,,,,,,,,,,\n");
    /* Values survive the text round trip to the precision the analysis needs. */
    double back = strtod(strstr(text, "1.250000,") + 9, NULL);
    assert_true(fabs(back - 0.39751) < 1e-12);
    free(text);
}

/* Issue 23: a restart (keep_previous, the rig) keeps the earlier run whole
 * as path.1 and shifts older ones as a rotation does; without it (the
 * simulator) the path is started again. */
static void restart_keeps_the_previous_run(void **state)
{
    (void)state;
    char path[300], err[200], name[320];
    snprintf(path, sizeof path, "%s/restart.csv", dir);
    for (int run = 0; run < 3; run++) {
        runlog_options o = {.path = path, .config_name = "c", .source = "rig", .keep_files = 5, .keep_previous = 1};
        runlog *log = runlog_open(&o, err, sizeof err);
        assert_non_null(log);
        for (int i = 0; i <= run; i++) { /* run k writes k + 1 rows */
            runlog_row r = sample_row(i * 0.01);
            assert_int_equal(runlog_write(log, &r), 0);
        }
        assert_int_equal(runlog_close(log), 0);
    }
    for (int k = 0; k < 3; k++) { /* path: the last run (3 rows), path.1: 2 rows, path.2: 1 row */
        if (k == 0)
            snprintf(name, sizeof name, "%s", path);
        else
            snprintf(name, sizeof name, "%s.%d", path, k);
        char *text = slurp(name, NULL);
        assert_non_null(text);
        assert_int_equal(check_complete_lines(text, strlen(text)), (size_t)(3 - k));
        free(text);
    }
    runlog_options fresh = {.path = path, .config_name = "c", .source = "sim"};
    runlog *log = runlog_open(&fresh, err, sizeof err);
    assert_non_null(log);
    assert_int_equal(runlog_close(log), 0);
    char *text = slurp(path, NULL);
    assert_int_equal(check_complete_lines(text, strlen(text)), 0);
    free(text);
    snprintf(name, sizeof name, "%s.3", path);
    assert_int_equal(access(name, F_OK), -1);
}

static void open_failure_names_the_path(void **state)
{
    (void)state;
    char err[200] = "";
    runlog_options o = {.path = "/nonexistent-dir/x/run.csv", .config_name = "c", .source = "sim"};
    assert_null(runlog_open(&o, err, sizeof err));
    assert_non_null(strstr(err, "/nonexistent-dir/x/run.csv"));
}

static void rotates_by_size_and_keeps_n_files(void **state)
{
    (void)state;
    char path[300], err[200], name[320];
    snprintf(path, sizeof path, "%s/rot.csv", dir);
    const size_t limit = 1000;
    runlog_options o = {.path = path, .config_name = "c", .source = "sim", .rotate_bytes = limit, .keep_files = 2};
    runlog *log = runlog_open(&o, err, sizeof err);
    assert_non_null(log);
    const int total = 100; /* ~60 bytes each: several rotations */
    for (int i = 0; i < total; i++) {
        runlog_row r = sample_row(i * 0.01);
        assert_int_equal(runlog_write(log, &r), 0);
    }
    assert_int_equal(runlog_close(log), 0);

    size_t rows = 0;
    char *last_first_row = NULL;
    for (int k = 2; k >= 0; k--) { /* oldest first */
        if (k == 0)
            snprintf(name, sizeof name, "%s", path);
        else
            snprintf(name, sizeof name, "%s.%d", path, k);
        size_t len;
        char *text = slurp(name, &len);
        assert_non_null(text);
        assert_true(len <= limit);
        assert_non_null(strstr(text, "# leveler run log, format 3\n"));
        rows += check_complete_lines(text, len);
        free(last_first_row);
        last_first_row = text;
    }
    free(last_first_row);
    snprintf(name, sizeof name, "%s.3", path);
    struct stat st;
    assert_int_equal(stat(name, &st), -1); /* the oldest file was removed */
    assert_true(rows > 0 && rows < (size_t)total);

    /* The newest file holds the last row written. */
    char *text = slurp(path, NULL);
    char want[32];
    snprintf(want, sizeof want, "\n%.6f,", (total - 1) * 0.01);
    assert_non_null(strstr(text, want));
    free(text);
}

static void sigterm_never_tears_a_line(void **state)
{
    (void)state;
    char path[300];
    snprintf(path, sizeof path, "%s/kill.csv", dir);
    for (int round = 0; round < 10; round++) {
        int buffered = round % 2; /* the rig's line-at-a-time log and the simulator's buffered one */
        unlink(path);
        pid_t pid = fork();
        assert_true(pid >= 0);
        if (pid == 0) {
            char err[200];
            /* the rig rotates; the simulator's buffered log does not */
            runlog_options o = {.path = path, .config_name = "c", .source = "rig",
                                .rotate_bytes = buffered ? 0 : 200000, .keep_files = 1, .buffered = buffered};
            runlog *log = runlog_open(&o, err, sizeof err);
            if (!log)
                _exit(3);
            for (long i = 0;; i++) {
                runlog_row r = sample_row(i * 0.01);
                if (runlog_write(log, &r) != 0)
                    _exit(4);
            }
        }
        /* Wait (bounded) until rows are being written, then let it run a
         * little more so the kill lands at a different point each round. */
        struct stat st;
        for (int waited = 0; waited < 5000 && !(stat(path, &st) == 0 && st.st_size > 4096); waited++) {
            struct timespec ms = {0, 1000000L};
            nanosleep(&ms, NULL);
        }
        struct timespec ts = {0, 1000000L + (round / 2) * 3000000L};
        nanosleep(&ts, NULL);
        kill(pid, SIGTERM); /* default action: killed between or inside write() calls */
        int status;
        assert_int_equal(waitpid(pid, &status, 0), pid);
        assert_true(WIFSIGNALED(status));
        size_t len;
        char *text = slurp(path, &len);
        assert_non_null(text);
        if (len && text[len - 1] != '\n')
            print_message("round %d buffered %d: %zu bytes, ends ...%s\n", round, buffered, len, text + (len > 200 ? len - 200 : 0));
        assert_true(check_complete_lines(text, len) > 0);
        free(text);
    }
}

/* /dev/null takes a log (nothing to fsync there), buffered or not. */
static void dev_null_is_a_log(void **state)
{
    (void)state;
    for (int buffered = 0; buffered <= 1; buffered++) {
        char err[200];
        runlog_options o = {.path = "/dev/null", .config_name = "c", .source = "sim", .buffered = buffered};
        runlog *log = runlog_open(&o, err, sizeof err);
        assert_non_null(log);
        for (int i = 0; i < 3000; i++) {
            runlog_row r = sample_row(i * 0.01);
            assert_int_equal(runlog_write(log, &r), 0);
        }
        assert_int_equal(runlog_close(log), 0);
    }
}

/* The buffered log holds the same bytes as the line-at-a-time one. */
static void buffered_log_has_the_same_bytes(void **state)
{
    (void)state;
    char paths[2][300];
    char *text[2];
    size_t len[2];
    for (int buffered = 0; buffered <= 1; buffered++) {
        snprintf(paths[buffered], sizeof paths[buffered], "%s/same%d.csv", dir, buffered);
        char err[200];
        runlog_options o = {.path = paths[buffered], .config_name = "c", .source = "sim", .buffered = buffered};
        runlog *log = runlog_open(&o, err, sizeof err);
        assert_non_null(log);
        for (int i = 0; i < 5000; i++) { /* more than one buffer's worth */
            runlog_row r = sample_row(i * 0.01);
            assert_int_equal(runlog_write(log, &r), 0);
        }
        assert_int_equal(runlog_close(log), 0);
        text[buffered] = slurp(paths[buffered], &len[buffered]);
        assert_non_null(text[buffered]);
    }
    assert_true(len[0] > 65536);
    assert_int_equal(len[0], len[1]);
    assert_memory_equal(text[0], text[1], len[0]);
    free(text[0]);
    free(text[1]);
}

/* The log's numbers are printf's "%.9g" and "%.6f", character for character
 * (decimal.h takes an exact integer path): glibc is the reference. */
static void numbers_are_printfs(void **state)
{
    (void)state;
    static const double edges[] = {0.0, -0.0, 1e-4, 9.99999999e-5, 1e8, 99999999.5, 0.5, 2.5, 1234567.125,
                                   0.395, 613633.1, 4003.4, 1e-5, 123456789.0, -0.39751, 5e-324, 1e300,
                                   0.1, 55.0, 54.99, 0.00999999999, 1e12, -1e-7};
    char mine[DECIMAL_MAX], ref[64];
    uint64_t x = 88172645463325252ull;
    for (int i = 0; i < 400000; i++) {
        double v;
        if (i < (int)(sizeof edges / sizeof edges[0])) {
            v = edges[i];
        } else {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            if (i % 3 == 0) {
                memcpy(&v, &x, sizeof v); /* any bit pattern */
                if (!isfinite(v))
                    continue;
            } else if (i % 3 == 1) {
                v = (double)(x >> 11) / 9007199254740992.0 * pow(10.0, (double)((int)(x % 16u) - 6));
            } else {
                v = (double)(int64_t)(x % 2000000000u) / pow(10.0, (double)(x % 12u)); /* decimal-looking */
            }
            if (x & 1u)
                v = -v;
        }
        decimal_g9(v, mine);
        snprintf(ref, sizeof ref, "%.9g", v);
        if (strcmp(mine, ref) != 0)
            fail_msg("%%.9g of %.17g: %s, printf %s", v, mine, ref);
        if (fabs(v) < 1e12) {
            decimal_f6(v, mine);
            snprintf(ref, sizeof ref, "%.6f", v);
            if (strcmp(mine, ref) != 0)
                fail_msg("%%.6f of %.17g: %s, printf %s", v, mine, ref);
        }
    }
}

/* In a child under a 4000-byte file-size limit (SIGXFSZ ignored, as
 * leveler-rig does): rows past the limit are dropped whole and counted, the
 * file keeps only complete lines; when the limit is lifted ("space returns")
 * logging resumes with whole lines and the fault clears. */
static void file_size_limit_drops_rows_whole_and_resumes(void **state)
{
    (void)state;
    char path[300], counts[320];
    snprintf(path, sizeof path, "%s/limit.csv", dir);
    snprintf(counts, sizeof counts, "%s/limit.counts", dir);
    pid_t pid = fork();
    if (pid == 0) {
        signal(SIGXFSZ, SIG_IGN);
        char err[256];
        runlog_options o = {.path = path, .config_name = "t", .source = "rig"};
        runlog *log = runlog_open(&o, err, sizeof err);
        struct rlimit rl;
        getrlimit(RLIMIT_FSIZE, &rl);
        struct rlimit tight = {.rlim_cur = 4000, .rlim_max = rl.rlim_max};
        if (log == NULL || setrlimit(RLIMIT_FSIZE, &tight) != 0)
            _exit(10);
        int written = 0, dropped = 0;
        for (int i = 0; i < 200; i++) {
            runlog_row row = sample_row(i * 0.01);
            if (runlog_write(log, &row) == 0)
                written++;
            else
                dropped++;
        }
        runlog_stats st = runlog_get_stats(log);
        if (st.rows_dropped != (unsigned long long)dropped || !st.fault)
            _exit(11);
        if (setrlimit(RLIMIT_FSIZE, &rl) != 0)
            _exit(12);
        for (int i = 0; i < 5; i++) {
            runlog_row row = sample_row(2.0 + i * 0.01);
            if (runlog_write(log, &row) != 0)
                _exit(13);
        }
        st = runlog_get_stats(log);
        if (st.fault || runlog_close(log) != 0)
            _exit(14);
        FILE *f = fopen(counts, "w");
        fprintf(f, "%d %d\n", written, dropped);
        fclose(f);
        _exit(0);
    }
    int status = 0;
    assert_int_equal(waitpid(pid, &status, 0), pid);
    assert_true(WIFEXITED(status));
    assert_int_equal(WEXITSTATUS(status), 0);
    int written = 0, dropped = 0;
    FILE *f = fopen(counts, "r");
    assert_non_null(f);
    assert_int_equal(fscanf(f, "%d %d", &written, &dropped), 2);
    fclose(f);
    print_message("4000-byte limit: %d rows written, %d dropped whole, then 5 more after the limit was lifted\n",
                  written, dropped);
    assert_true(written > 10 && dropped > 100);
    size_t len;
    char *text = slurp(path, &len);
    assert_non_null(text);
    assert_int_equal(check_complete_lines(text, len), (size_t)written + 5);
    free(text);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(writes_header_and_rows_with_empty_cells),
        cmocka_unit_test(open_failure_names_the_path),
        cmocka_unit_test(restart_keeps_the_previous_run),
        cmocka_unit_test(rotates_by_size_and_keeps_n_files),
        cmocka_unit_test(sigterm_never_tears_a_line),
        cmocka_unit_test(dev_null_is_a_log),
        cmocka_unit_test(buffered_log_has_the_same_bytes),
        cmocka_unit_test(numbers_are_printfs),
        cmocka_unit_test(file_size_limit_drops_rows_whole_and_resumes),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
