/* The Modbus link to the rig's I/O module (modbus_link.h). */
#define _POSIX_C_SOURCE 200809L
#include "modbus_link.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <unistd.h>
#include <stdlib.h>
#include <time.h>

struct rig_link {
    const rig_config *cfg;
    modbus_t *ctx;
    bool connected;
    bool retry_now;          /* a dropped connection is retried at once, a refused one once a second */
    struct timespec last_try;
    uint32_t failures_in_row;
    uint32_t reconnect_after; /* failures in a row before the next reconnect: 3, doubling to 100 */
    rig_link_stats stats;
    struct timespec last_said;  /* connect failures: said at once, then every 10 s with a count */
    uint32_t unsaid;
};

static double seconds_since(const struct timespec *t)
{
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (double)(now.tv_sec - t->tv_sec) + 1e-9 * (double)(now.tv_nsec - t->tv_nsec);
}

static void try_connect(rig_link *l)
{
    clock_gettime(CLOCK_MONOTONIC, &l->last_try);
    l->retry_now = false;
    if (modbus_connect(l->ctx) == 0) {
        l->connected = true;
        l->stats.connects++;
        return;
    }
    if (l->unsaid > 0 && seconds_since(&l->last_said) < 10.0) {
        l->unsaid++;
        return;
    }
    fprintf(stderr, "leveler-rig: I/O module: connect failed: %s (retrying every second; %u failures not shown)\n",
            modbus_strerror(errno), l->unsaid > 0 ? l->unsaid - 1 : 0);
    clock_gettime(CLOCK_MONOTONIC, &l->last_said);
    l->unsaid = 1;
}

rig_link *rig_link_open(const rig_config *cfg, char *err, size_t err_len)
{
    rig_link *l = calloc(1, sizeof *l);
    if (l == NULL) {
        snprintf(err, err_len, "I/O module: out of memory");
        return NULL;
    }
    l->cfg = cfg;
    l->reconnect_after = RIG_LINK_RECONNECT_AFTER;
    if (cfg->transport == RIG_TRANSPORT_TCP) {
        char port[16];
        snprintf(port, sizeof port, "%u", cfg->port);
        l->ctx = modbus_new_tcp_pi(cfg->host, port);
    } else {
        l->ctx = modbus_new_rtu(cfg->device, (int)cfg->baud, cfg->parity, cfg->data_bits, cfg->stop_bits);
    }
    if (l->ctx == NULL) {
        snprintf(err, err_len, "I/O module: [sensors] %s: %s",
                 cfg->transport == RIG_TRANSPORT_TCP ? "host/port" : "device/baud/parity", modbus_strerror(errno));
        free(l);
        return NULL;
    }
    modbus_set_slave(l->ctx, cfg->slave);
    uint32_t us = cfg->timeout_ms * 1000u;
    modbus_set_response_timeout(l->ctx, us / 1000000u, us % 1000000u);
    modbus_set_byte_timeout(l->ctx, us / 1000000u, us % 1000000u);
    try_connect(l);
    return l;
}

void rig_link_close(rig_link *l)
{
    if (l == NULL)
        return;
    modbus_close(l->ctx);
    modbus_free(l->ctx);
    free(l);
}

modbus_t *rig_link_begin(rig_link *l)
{
    if (!l->connected && (l->retry_now || seconds_since(&l->last_try) >= 1.0))
        try_connect(l);
    if (!l->connected)
        return NULL;
    modbus_flush(l->ctx); /* a late reply to an earlier request must not answer this one */
    return l->ctx;
}

static bool link_is_dead(int e)
{
    return e == ECONNRESET || e == EPIPE || e == EBADF || e == ENOTCONN || e == ECONNREFUSED;
}

/* RTU after a failed request: the reply may still be on its way and would be
 * taken as the next request's answer (RTU replies carry no transaction id).
 * Bytes are read and discarded until the line has been quiet for the reply
 * timeout (at most RIG_LINK_DRAIN_MAX windows), then the next request goes
 * out: a reply later than twice the timeout is a module fault, not data. */
static void drain_late_reply(rig_link *l)
{
    int fd = modbus_get_socket(l->ctx);
    int window_ms = (int)l->cfg->timeout_ms;
    uint8_t junk[256];
    for (int n = 0; fd >= 0 && n < RIG_LINK_DRAIN_MAX; n++) {
        struct pollfd p = {.fd = fd, .events = POLLIN};
        if (poll(&p, 1, window_ms < 1 ? 1 : window_ms) <= 0 || read(fd, junk, sizeof junk) <= 0)
            break; /* quiet for a whole window */
        l->stats.late_bytes_discarded++;
    }
    modbus_flush(l->ctx);
}

void rig_link_end(rig_link *l, bool ok)
{
    if (ok) {
        l->failures_in_row = 0;
        l->reconnect_after = RIG_LINK_RECONNECT_AFTER;
        return;
    }
    int e = errno;
    l->stats.failed_requests++;
    l->failures_in_row++;
    bool tcp = l->cfg->transport == RIG_TRANSPORT_TCP;
    if (tcp && (link_is_dead(e) || l->failures_in_row >= l->reconnect_after)) {
        /* A fresh connection carries nothing stale: reconnect on the next
         * request. A module that stays silent gets fewer and fewer new
         * connections (a stopped one still accepts them into its backlog). */
        modbus_close(l->ctx);
        l->connected = false;
        l->retry_now = true;
        l->failures_in_row = 0;
        l->reconnect_after = l->reconnect_after >= 50 ? 100 : 2 * l->reconnect_after;
        l->stats.reconnects++;
        return;
    }
    if (!tcp) /* a timeout, or a garbled (partial, late) reply */
        drain_late_reply(l);
    else
        modbus_flush(l->ctx);
}

rig_link_stats rig_link_get_stats(const rig_link *l)
{
    return l->stats;
}
