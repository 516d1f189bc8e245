/*
 * Run-log writer: one CSV format for simulator, rig and diagnosis
 * (docs/log-format.md). SI units, absolute pressures.
 *
 *   # leveler run log, format 3
 *   # config: thesis-900lb
 *   # source: sim            (or rig)
 *   t_s,height_m,p_spring_pa,p_pipe_pa,p_acc_pa,load_n,compressor,spring_valve,vent_valve,acc_valve,
 *   mode,control_state,latched_fault_bits,sensors_valid,true_height_m,true_p_spring_pa,true_p_pipe_pa,true_p_acc_pa
 *
 * height and pressures are what the firmware read (its register map's
 * height_um, p_*_pa); true_* the plant's state (simulated runs only).
 *
 * Lines are written whole, so a process stopped by SIGTERM leaves no torn
 * line: one write per line with fsync on rotation and close (the rig), or
 * whole lines collected in a 64 KiB buffer (buffered: the simulator).
 * A line the disk refuses (full, I/O error, file-size limit) is dropped whole
 * and counted; the file is cut back to its last complete line. Optional
 * rotation by size.
 */
#ifndef LEVELER_RUNLOG_H
#define LEVELER_RUNLOG_H

#include <stddef.h>

#define RUNLOG_FORMAT_VERSION 3

typedef struct {
    double t_s;
    double height_m;
    double p_spring_pa; /* NAN = not measured: empty cell */
    double p_pipe_pa;   /* NAN = empty */
    double p_acc_pa;    /* NAN = empty */
    double load_n;
    int compressor;     /* 0/1, -1 = empty */
    int spring_valve;
    int vent_valve;
    int acc_valve;
    /* the firmware's state after the tick (registers.json names); -1 = empty */
    int mode;               /* leveler_mode */
    int control_state;      /* leveler_control_state */
    int latched_fault_bits; /* LEVELER_FAULT_BIT(code) */
    int sensors_valid;      /* 0/1 */
    /* the plant's true state (simulated runs); NAN = empty */
    double true_height_m, true_p_spring_pa, true_p_pipe_pa, true_p_acc_pa;
} runlog_row;

/* A row with every optional cell empty (NAN / -1); t, height and load to be set. */
runlog_row runlog_row_empty(void);

typedef struct {
    const char *path;         /* "-" = stdout */
    const char *config_name;
    const char *source;       /* "sim" or "rig" */
    size_t rotate_bytes;      /* 0 = never rotate; else start path.1, path.2 ... past this size */
    unsigned keep_files;      /* rotated files kept (oldest removed) */
    int buffered;             /* 1: whole lines collected and written together, no fsync (the simulator) */
    int keep_previous;        /* 1: an existing non-empty path is kept as path.1 (rotation's shift), never
                                 truncated (the rig: a restart after a crash keeps the failed run's log) */
} runlog_options;

typedef struct runlog runlog;

/* NULL on failure, with a message naming the path in err. */
runlog *runlog_open(const runlog_options *options, char *err, size_t err_len);
/* 0 on success, -1 when the row was dropped (errno set; the file still ends
 * with a complete line). */
int runlog_write(runlog *log, const runlog_row *row);

typedef struct {
    unsigned long long rows_written;  /* since open (rotated files and the buffer included) */
    unsigned long long rows_dropped;
    int fault; /* the last row was dropped */
} runlog_stats;
runlog_stats runlog_get_stats(const runlog *log);
/* Flush, fsync (line-buffered logs) and close. 0 on success. */
int runlog_close(runlog *log);

#endif /* LEVELER_RUNLOG_H */
