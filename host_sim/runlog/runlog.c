/*
 * Run-log writer (runlog.h, docs/log-format.md).
 *
 * Every line is formatted into a buffer first. A line-buffered log (the rig)
 * hands each line to the kernel with one write() (looping only on a partial
 * write or EINTR) and fsyncs at close; a buffered log (the simulator) collects
 * whole lines in RUNLOG_BUFFER_BYTES and writes them together. Either way no
 * stdio buffer is involved and only whole lines reach the file, so a reader
 * of a process stopped by SIGTERM sees whole lines.
 * A line that cannot be written whole (ENOSPC, EIO, EFBIG past a file-size
 * limit) is dropped whole: the file is truncated back to the end of the last
 * complete line (files are opened O_APPEND, so the next write lands there),
 * the row is counted in rows_dropped and the log is marked faulty until a
 * line is written again, so the file always reads as whole lines and logging
 * resumes by itself when space returns (a buffered log drops what it held).
 * Rotation: when the next line would push the current file past rotate_bytes,
 * the file is fsync'ed, path.(k) -> path.(k+1) for k = keep-1..1, path ->
 * path.1, and a fresh path starts with the same header and that line; path
 * exists at every moment (rotate()).
 */
#define _POSIX_C_SOURCE 200809L
#include "runlog.h"

#include "decimal.h"
#include "leveler/version.h" /* in the header: a log names the code that made it */

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define RUNLOG_LINE_MAX 512
#define RUNLOG_HEADER_MAX 1024
#define RUNLOG_BUFFER_BYTES 65536

struct runlog {
    int fd;
    int is_stdout;
    char *path;
    size_t rotate_bytes;
    unsigned keep_files;
    size_t file_bytes; /* bytes in the current file, header included */
    char header[RUNLOG_HEADER_MAX];
    size_t header_len;
    char *buf; /* buffered logs: whole lines not yet written */
    size_t buf_len;
    unsigned long long buf_rows;      /* rows in buf */
    unsigned long long rows_written;  /* rows in the file (buffered ones included) */
    unsigned long long rows_dropped;
    int fault;      /* the last row was dropped */
    int needs_trim; /* a truncation back to the last complete line is still owed */
};

static int write_all(int fd, const char *buf, size_t len)
{
    while (len > 0) {
        ssize_t n = write(fd, buf, len);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            return -1;
        }
        buf += n;
        len -= (size_t)n;
    }
    return 0;
}

/* Whatever part of a failed write reached the file goes again; 0 once the
 * file ends at its last complete line. */
static int trim_torn_tail(runlog *log)
{
    if (!log->needs_trim)
        return 0;
    if (log->is_stdout || ftruncate(log->fd, (off_t)(log->file_bytes - log->buf_len)) == 0) {
        log->needs_trim = 0;
        return 0;
    }
    return -1;
}

/* A fatal signal can cut a large write() to a file short at a page boundary,
 * so the buffer goes out with signals held: a SIGTERM then lands after it. */
static int flush_buffer(runlog *log)
{
    if (log->buf_len == 0)
        return 0;
    sigset_t all, old;
    sigfillset(&all);
    sigprocmask(SIG_BLOCK, &all, &old);
    int rc = trim_torn_tail(log) == 0 ? write_all(log->fd, log->buf, log->buf_len) : -1;
    sigprocmask(SIG_SETMASK, &old, NULL);
    if (rc != 0) { /* the buffered rows are dropped whole and counted */
        int e = errno;
        log->file_bytes -= log->buf_len;
        log->rows_written -= log->buf_rows;
        log->rows_dropped += log->buf_rows;
        log->fault = 1;
        log->needs_trim = 1;
        log->buf_len = 0;
        trim_torn_tail(log);
        errno = e;
    }
    log->buf_len = 0;
    log->buf_rows = 0;
    return rc;
}

/* O_APPEND: after a torn line is cut off, the next write lands at the new end. */
static int open_fresh(runlog *log)
{
    log->fd = open(log->path, O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0666);
    if (log->fd < 0)
        return -1;
    log->file_bytes = 0;
    if (write_all(log->fd, log->header, log->header_len) != 0)
        return -1;
    log->file_bytes = log->header_len;
    return 0;
}

/* path.N into buf; -1 if it does not fit. */
static int numbered_path(char *buf, size_t cap, const char *path, unsigned n)
{
    int len = snprintf(buf, cap, "%s.%u", path, n);
    return (len < 0 || (size_t)len >= cap) ? -1 : 0;
}

/* Drops path.keep, shifts path.k to path.(k+1) for k = keep-1..1 and leaves
 * "path.1" in to (from, to: cap bytes each), ready for path to become path.1. */
static int shift_numbered(const char *path, unsigned keep, char *from, char *to, size_t cap)
{
    numbered_path(to, cap, path, keep);
    if (unlink(to) != 0 && errno != ENOENT)
        return -1;
    for (unsigned k = keep - 1; k >= 1; k--) {
        numbered_path(from, cap, path, k);
        numbered_path(to, cap, path, k + 1);
        if (rename(from, to) != 0 && errno != ENOENT)
            return -1;
    }
    numbered_path(to, cap, path, 1);
    return 0;
}

/* keep_previous: a non-empty path left by an earlier run (a crash, a
 * restart by systemd) becomes path.1 as at a rotation (at least one kept), so
 * a start never destroys the log of the run before it. */
static int keep_previous_run(const runlog *log)
{
    struct stat st;
    if (stat(log->path, &st) != 0)
        return errno == ENOENT ? 0 : -1;
    if (!S_ISREG(st.st_mode) || st.st_size == 0)
        return 0;
    size_t cap = strlen(log->path) + 16;
    char *from = malloc(cap), *to = malloc(cap);
    int rc = from && to && shift_numbered(log->path, log->keep_files > 0 ? log->keep_files : 1, from, to, cap) == 0 &&
                     rename(log->path, to) == 0
                 ? 0
                 : -1;
    free(from);
    free(to);
    return rc;
}

/* Rotation keeps path in place at every moment, with whole lines and at
 * least one row: the next file (header + the line that did not fit) is
 * written as path.tmp, the full one is linked to path.1 (older ones shifted
 * up first) and path.tmp is renamed over path. */
static int rotate(runlog *log, const char *line, size_t len)
{
    if (flush_buffer(log) != 0 || fsync(log->fd) != 0)
        return -1;
    size_t cap = strlen(log->path) + 16;
    char *tmp = malloc(cap), *from = malloc(cap), *to = malloc(cap);
    int rc = -1, fd = -1;
    if (tmp == NULL || from == NULL || to == NULL)
        goto out;
    snprintf(tmp, cap, "%s.tmp", log->path);
    fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0666);
    if (fd < 0 || write_all(fd, log->header, log->header_len) != 0 || write_all(fd, line, len) != 0)
        goto out;
    if (log->keep_files > 0 && (shift_numbered(log->path, log->keep_files, from, to, cap) != 0 ||
                                link(log->path, to) != 0))
        goto out;
    if (rename(tmp, log->path) != 0)
        goto out;
    close(log->fd);
    log->fd = fd;
    fd = -1;
    log->file_bytes = log->header_len + len;
    rc = 0;
out:
    if (fd >= 0)
        close(fd);
    free(tmp);
    free(from);
    free(to);
    return rc;
}

runlog *runlog_open(const runlog_options *options, char *err, size_t err_len)
{
    if (options == NULL || options->path == NULL || options->path[0] == '\0') {
        snprintf(err, err_len, "runlog: no path given");
        return NULL;
    }
    runlog *log = calloc(1, sizeof *log);
    if (log == NULL) {
        snprintf(err, err_len, "runlog: %s: out of memory", options->path);
        return NULL;
    }
    log->fd = -1;
    log->is_stdout = strcmp(options->path, "-") == 0;
    log->rotate_bytes = log->is_stdout ? 0 : options->rotate_bytes;
    log->keep_files = options->keep_files;
    log->path = strdup(options->path);
    if (options->buffered && log->path)
        log->buf = malloc(RUNLOG_BUFFER_BYTES);
    int hlen = snprintf(log->header, sizeof log->header,
                        "# leveler run log, format %d\n# config: %s\n# source: %s\n# version: %s\n"
                        "t_s,height_m,p_spring_pa,p_pipe_pa,p_acc_pa,load_n,"
                        "compressor,spring_valve,vent_valve,acc_valve,"
                        "mode,control_state,latched_fault_bits,sensors_valid,"
                        "true_height_m,true_p_spring_pa,true_p_pipe_pa,true_p_acc_pa\n",
                        RUNLOG_FORMAT_VERSION,
                        options->config_name ? options->config_name : "",
                        options->source ? options->source : "", LEVELER_VERSION);
    if (log->path == NULL || (options->buffered && log->buf == NULL)) {
        snprintf(err, err_len, "runlog: %s: out of memory", options->path);
        free(log->buf);
        free(log->path);
        free(log);
        return NULL;
    }
    if (hlen < 0 || (size_t)hlen >= sizeof log->header) {
        snprintf(err, err_len, "runlog: %s: header too long (config or source name)", options->path);
        free(log->buf);
        free(log->path);
        free(log);
        return NULL;
    }
    log->header_len = (size_t)hlen;
    if (log->is_stdout) {
        log->fd = STDOUT_FILENO;
        if (write_all(log->fd, log->header, log->header_len) != 0) {
            snprintf(err, err_len, "runlog: stdout: %s", strerror(errno));
            free(log->buf);
            free(log->path);
            free(log);
            return NULL;
        }
        return log;
    }
    if ((options->keep_previous && keep_previous_run(log) != 0) || open_fresh(log) != 0) {
        snprintf(err, err_len, "runlog: %s: %s", options->path, strerror(errno));
        if (log->fd >= 0)
            close(log->fd);
        free(log->buf);
        free(log->path);
        free(log);
        return NULL;
    }
    return log;
}

/* Appends to a fixed line buffer; any overflow sticks and fails the line. */
typedef struct {
    char buf[RUNLOG_LINE_MAX];
    size_t len;
    int overflow;
} line_buffer;

static void append(line_buffer *line, const char *text, size_t n)
{
    if (line->overflow || n >= sizeof line->buf - line->len) {
        line->overflow = 1;
        return;
    }
    memcpy(line->buf + line->len, text, n);
    line->len += n;
}

/* Room for one more cell, formatted in place. */
static char *cell(line_buffer *line)
{
    if (line->overflow || sizeof line->buf - line->len < DECIMAL_MAX + 2) {
        line->overflow = 1;
        return NULL;
    }
    return line->buf + line->len;
}

/* A measurement, %.9g (decimal.h); not-a-number (not measured) or infinite -> empty cell. */
static void put_number(line_buffer *line, double v)
{
    char *c = cell(line);
    if (c) {
        c[0] = ',';
        line->len += 1 + (isfinite(v) ? decimal_g9(v, c + 1) : 0);
    }
}

/* An actuator state 0/1; -1 (unknown) -> empty cell. */
static void put_flag(line_buffer *line, int v)
{
    char *c = cell(line);
    if (c) {
        c[0] = ',';
        c[1] = v ? '1' : '0';
        line->len += v < 0 ? 1 : 2;
    }
}

/* A small non-negative integer (mode, state, fault bits); negative -> empty cell. */
static void put_int(line_buffer *line, int v)
{
    char *c = cell(line);
    if (c) {
        c[0] = ',';
        line->len += 1 + (v < 0 ? 0 : (size_t)snprintf(c + 1, DECIMAL_MAX, "%d", v));
    }
}

runlog_row runlog_row_empty(void)
{
    return (runlog_row){.p_spring_pa = NAN, .p_pipe_pa = NAN, .p_acc_pa = NAN, .compressor = -1, .spring_valve = -1,
                        .vent_valve = -1, .acc_valve = -1, .mode = -1, .control_state = -1,
                        .latched_fault_bits = -1, .sensors_valid = -1, .true_height_m = NAN,
                        .true_p_spring_pa = NAN, .true_p_pipe_pa = NAN, .true_p_acc_pa = NAN};
}

/* One formatted line into the file, the buffer or the next rotated file;
 * -1 if it did not get there whole (the file then ends at its last whole line). */
static int store_line(runlog *log, const char *line, size_t len)
{
    if (log->rotate_bytes > 0 && log->file_bytes > log->header_len && log->file_bytes + len > log->rotate_bytes)
        return rotate(log, line, len); /* the line starts the next file; on failure the old one stays */
    if (log->buf) {
        if (log->buf_len + len > RUNLOG_BUFFER_BYTES)
            flush_buffer(log); /* on failure what it held is dropped and counted; this line is not in it */
        memcpy(log->buf + log->buf_len, line, len);
        log->buf_len += len;
        log->buf_rows++;
        log->file_bytes += len;
        return 0;
    }
    if (trim_torn_tail(log) != 0)
        return -1;
    if (write_all(log->fd, line, len) != 0) {
        int e = errno;
        log->needs_trim = 1;
        trim_torn_tail(log);
        errno = e;
        return -1;
    }
    log->file_bytes += len;
    return 0;
}

int runlog_write(runlog *log, const runlog_row *row)
{
    if (log == NULL || row == NULL || log->fd < 0) {
        errno = EBADF;
        return -1;
    }
    line_buffer line = {.len = 0, .overflow = 0};
    line.len = decimal_f6(row->t_s, line.buf);
    put_number(&line, row->height_m);
    put_number(&line, row->p_spring_pa);
    put_number(&line, row->p_pipe_pa);
    put_number(&line, row->p_acc_pa);
    put_number(&line, row->load_n);
    put_flag(&line, row->compressor);
    put_flag(&line, row->spring_valve);
    put_flag(&line, row->vent_valve);
    put_flag(&line, row->acc_valve);
    put_int(&line, row->mode);
    put_int(&line, row->control_state);
    put_int(&line, row->latched_fault_bits);
    put_flag(&line, row->sensors_valid);
    put_number(&line, row->true_height_m);
    put_number(&line, row->true_p_spring_pa);
    put_number(&line, row->true_p_pipe_pa);
    put_number(&line, row->true_p_acc_pa);
    append(&line, "\n", 1);
    if (line.overflow) {
        errno = EOVERFLOW;
        log->rows_dropped++;
        log->fault = 1;
        return -1;
    }
    if (store_line(log, line.buf, line.len) != 0) {
        log->rows_dropped++;
        log->fault = 1;
        return -1;
    }
    log->rows_written++;
    log->fault = 0;
    return 0;
}

runlog_stats runlog_get_stats(const runlog *log)
{
    runlog_stats st = {.rows_written = log->rows_written, .rows_dropped = log->rows_dropped, .fault = log->fault};
    return st;
}

/* fsync where it means something: pipes, terminals and /dev/null cannot be
 * synced (EINVAL, EROFS) and have nothing to lose. */
static int sync_fd(int fd)
{
    return fsync(fd) != 0 && errno != EINVAL && errno != EROFS ? -1 : 0;
}

int runlog_close(runlog *log)
{
    if (log == NULL)
        return 0;
    int rc = 0;
    if (log->fd < 0) {
        rc = -1;
    } else {
        if (flush_buffer(log) != 0)
            rc = -1;
        /* the rig's log is fsync'ed; the simulator's (buffered) is the page cache's */
        if (!log->buf && sync_fd(log->fd) != 0)
            rc = -1;
        if (!log->is_stdout && close(log->fd) != 0)
            rc = -1;
    }
    free(log->buf);
    free(log->path);
    free(log);
    return rc;
}
