#define _GNU_SOURCE /* accept4 */
#include "supervision.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <modbus.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include "leveler/regmap.h"

#define MBAP_LEN 7
#define FRAME_MAX (MBAP_LEN + 253)
#define FRAMES_PER_CLIENT_PER_CALL 8

typedef struct {
    int fd;
    uint8_t buf[FRAME_MAX];
    size_t len;
    uint64_t last_request_ms; /* last complete request (or the connect): the idle timer */
    uint64_t partial_since_ms; /* first byte of the request in buf: the request deadline */
    uint32_t served;           /* complete requests handled */
    bool may_write;            /* its address is in [supervision] writers (or there is no list) */
} client;

struct rig_supervision {
    modbus_t *ctx;               /* reply builder; its socket is set per client */
    modbus_mapping_t *mapping;   /* refreshed from the register map before each read */
    int listen_fd;
    int unix_fd;                 /* [supervision] write_socket, or -1 */
    uint16_t port;
    bool read_only;
    uint32_t idle_timeout_ms;
    uint32_t request_timeout_ms;
    uint32_t max_clients;
    const rig_config *cfg;
    client *clients;
    rig_supervision_stats stats;
};

static uint64_t now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000u + (uint64_t)t.tv_nsec / 1000000u;
}

/* A non-blocking listening socket on a numeric IPv4/IPv6 address (libmodbus's
 * own listener is IPv4 only and reads any text as an address). */
static int listen_on(const char *address, uint16_t port, uint16_t *bound_port, char *err, size_t err_len)
{
    struct addrinfo hints = {.ai_flags = AI_PASSIVE | AI_NUMERICHOST | AI_NUMERICSERV, .ai_socktype = SOCK_STREAM};
    struct addrinfo *ai = NULL;
    char service[8];
    snprintf(service, sizeof service, "%u", port);
    int rc = getaddrinfo(address, service, &hints, &ai);
    if (rc != 0) {
        snprintf(err, err_len, "supervision: [supervision] address '%s': %s", address, gai_strerror(rc));
        return -1;
    }
    int fd = socket(ai->ai_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    int one = 1;
    if (fd < 0 || setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0 ||
        bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || listen(fd, 16) != 0) {
        snprintf(err, err_len, "supervision: [supervision] address/port: cannot listen on %s port %u: %s", address,
                 port, strerror(errno));
        if (fd >= 0)
            close(fd);
        freeaddrinfo(ai);
        return -1;
    }
    freeaddrinfo(ai);
    struct sockaddr_storage sa;
    socklen_t alen = sizeof sa;
    getsockname(fd, (struct sockaddr *)&sa, &alen);
    *bound_port = ntohs(sa.ss_family == AF_INET6 ? ((struct sockaddr_in6 *)&sa)->sin6_port
                                                 : ((struct sockaddr_in *)&sa)->sin_port);
    return fd;
}

/* [supervision] write_socket: a Unix socket, owner and group only (0660), so
 * only processes with those rights (leveler-mbaps) can connect and write; a
 * socket left by an earlier run is replaced, any other file is an error. */
static int listen_on_unix(const char *path, char *err, size_t err_len)
{
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    struct stat st;
    if (strlen(path) >= sizeof sa.sun_path) {
        snprintf(err, err_len, "supervision: [supervision] write_socket: '%s' longer than %zu bytes", path,
                 sizeof sa.sun_path - 1);
        return -1;
    }
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", path);
    if (lstat(path, &st) == 0 && S_ISSOCK(st.st_mode))
        unlink(path);
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    mode_t old = umask(0117);
    int rc = fd < 0 ? -1 : bind(fd, (struct sockaddr *)&sa, sizeof sa);
    umask(old);
    if (rc != 0 || listen(fd, 16) != 0) {
        snprintf(err, err_len, "supervision: [supervision] write_socket: cannot listen on %s: %s", path,
                 strerror(errno));
        if (fd >= 0)
            close(fd);
        return -1;
    }
    return fd;
}

rig_supervision *rig_supervision_open(const rig_config *cfg, char *err, size_t err_len)
{
    rig_supervision *sv = calloc(1, sizeof *sv);
    if (sv == NULL) {
        snprintf(err, err_len, "supervision: out of memory");
        return NULL;
    }
    sv->cfg = cfg;
    sv->read_only = cfg->read_only;
    sv->idle_timeout_ms = cfg->idle_timeout_ms;
    sv->request_timeout_ms = cfg->request_timeout_ms;
    sv->max_clients = cfg->max_clients;
    sv->clients = calloc(cfg->max_clients, sizeof *sv->clients);
    for (uint32_t i = 0; sv->clients && i < cfg->max_clients; i++)
        sv->clients[i].fd = -1;
    sv->ctx = modbus_new_tcp("127.0.0.1", MODBUS_TCP_DEFAULT_PORT); /* builds replies only; never connects */
    sv->mapping = modbus_mapping_new(leveler_regs_table_size(LEVELER_TABLE_COIL),
                                     leveler_regs_table_size(LEVELER_TABLE_DISCRETE_INPUT),
                                     leveler_regs_table_size(LEVELER_TABLE_HOLDING_REGISTER),
                                     leveler_regs_table_size(LEVELER_TABLE_INPUT_REGISTER));
    sv->listen_fd = -1;
    sv->unix_fd = -1;
    if (sv->clients == NULL || sv->ctx == NULL || sv->mapping == NULL) {
        snprintf(err, err_len, "supervision: out of memory");
        rig_supervision_close(sv);
        return NULL;
    }
    sv->listen_fd = listen_on(cfg->supervision_address, cfg->supervision_port, &sv->port, err, err_len);
    if (sv->listen_fd >= 0 && cfg->write_socket[0])
        sv->unix_fd = listen_on_unix(cfg->write_socket, err, err_len);
    if (sv->listen_fd < 0 || (cfg->write_socket[0] && sv->unix_fd < 0)) {
        rig_supervision_close(sv);
        return NULL;
    }
    return sv;
}

uint16_t rig_supervision_port(const rig_supervision *sv)
{
    return sv->port;
}

rig_supervision_stats rig_supervision_get_stats(const rig_supervision *sv)
{
    return sv->stats;
}

static uint16_t be16(const uint8_t *p)
{
    return (uint16_t)((p[0] << 8) | p[1]);
}

static void drop(client *c)
{
    close(c->fd);
    c->fd = -1;
    c->len = 0;
}

/* The peer's address as [supervision] writers spells it (IPv4-mapped IPv6 as IPv4). */
static bool peer_may_write(const rig_supervision *sv, int fd)
{
    if (sv->cfg->writer_count == 0)
        return true;
    struct sockaddr_storage sa;
    socklen_t len = sizeof sa;
    char text[INET6_ADDRSTRLEN] = "";
    if (getpeername(fd, (struct sockaddr *)&sa, &len) != 0)
        return false;
    if (sa.ss_family == AF_INET) {
        inet_ntop(AF_INET, &((struct sockaddr_in *)&sa)->sin_addr, text, sizeof text);
    } else {
        const struct in6_addr *a = &((struct sockaddr_in6 *)&sa)->sin6_addr;
        if (IN6_IS_ADDR_V4MAPPED(a))
            inet_ntop(AF_INET, &a->s6_addr[12], text, sizeof text);
        else
            inet_ntop(AF_INET6, a, text, sizeof text);
    }
    for (uint32_t i = 0; i < sv->cfg->writer_count; i++)
        if (!strcmp(text, sv->cfg->writers[i]))
            return true;
    return false;
}

static bool has_frame(const client *c)
{
    return c->len >= MBAP_LEN && c->len >= 6u + be16(c->buf + 4);
}

/* A new connection's time to send its first whole request before a newer
 * one may take its slot (two ticks: a real client sends it at once). */
#define NEW_CLIENT_GRACE_MS 20u

/* A free slot, or the slot of a client that may make room: one that never
 * completed a request and is older than NEW_CLIENT_GRACE_MS (oldest first),
 * else one with no complete request for request_timeout_ms (longest idle
 * first), else (every slot held by clients that keep polling) the least
 * recently active one with nothing buffered, quiet for NEW_CLIENT_GRACE_MS:
 * it gives way, so a fifth poller is not shut out by four. NULL: every slot
 * is mid-request; new connections wait in the backlog. */
static client *slot_for_new(rig_supervision *sv, uint64_t now, bool *least_active)
{
    client *victim = NULL, *fallback = NULL;
    *least_active = false;
    for (uint32_t i = 0; i < sv->max_clients; i++) {
        client *c = &sv->clients[i];
        if (c->fd < 0)
            return c;
        uint64_t quiet = now - c->last_request_ms;
        if (has_frame(c) || quiet < NEW_CLIENT_GRACE_MS)
            continue;
        if (c->len == 0 && (fallback == NULL || c->last_request_ms < fallback->last_request_ms))
            fallback = c;
        if (quiet < (c->served ? sv->request_timeout_ms : NEW_CLIENT_GRACE_MS))
            continue;
        if (victim == NULL || (c->served == 0 && victim->served != 0) ||
            ((c->served == 0) == (victim->served == 0) && c->last_request_ms < victim->last_request_ms))
            victim = c;
    }
    if (victim == NULL && fallback != NULL) {
        *least_active = true;
        return fallback;
    }
    return victim;
}

/* Accepts while there is room (see slot_for_new); the rest stays in the
 * kernel's backlog, in order, for the next call. */
static void accept_clients(rig_supervision *sv, int listen_fd)
{
    for (int n = 0; n < 8; n++) {
        uint64_t now = now_ms();
        bool least_active;
        client *slot = slot_for_new(sv, now, &least_active);
        if (slot == NULL)
            return;
        int fd = accept4(listen_fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0)
            return;
        if (slot->fd >= 0) {
            drop(slot);
            sv->stats.evicted++;
            sv->stats.evicted_active += least_active;
        }
        /* With a write_socket only its clients write; else [supervision] writers decides. */
        bool may_write = listen_fd == sv->unix_fd || (sv->unix_fd < 0 && peer_may_write(sv, fd));
        *slot = (client){.fd = fd, .last_request_ms = now, .may_write = may_write};
        sv->stats.accepted++;
    }
}

static leveler_table table_of(int function)
{
    switch (function) {
    case MODBUS_FC_READ_COILS:
    case MODBUS_FC_WRITE_SINGLE_COIL:
    case MODBUS_FC_WRITE_MULTIPLE_COILS:
        return LEVELER_TABLE_COIL;
    case MODBUS_FC_READ_DISCRETE_INPUTS:
        return LEVELER_TABLE_DISCRETE_INPUT;
    case MODBUS_FC_READ_INPUT_REGISTERS:
        return LEVELER_TABLE_INPUT_REGISTER;
    default:
        return LEVELER_TABLE_HOLDING_REGISTER;
    }
}

static int exception_for(leveler_reg_status st)
{
    return st == LEVELER_REG_ILLEGAL_ADDRESS ? MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS
                                             : MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE;
}

/* Copies the register map's current values into the libmodbus mapping. */
static void refresh_mapping(rig_supervision *sv, leveler_table table, uint16_t addr, uint16_t count,
                            const uint16_t *values)
{
    for (uint16_t i = 0; i < count; i++) {
        uint16_t v = values[i];
        switch (table) {
        case LEVELER_TABLE_COIL: sv->mapping->tab_bits[addr + i] = (uint8_t)(v != 0); break;
        case LEVELER_TABLE_DISCRETE_INPUT: sv->mapping->tab_input_bits[addr + i] = (uint8_t)(v != 0); break;
        case LEVELER_TABLE_HOLDING_REGISTER: sv->mapping->tab_registers[addr + i] = v; break;
        case LEVELER_TABLE_INPUT_REGISTER: sv->mapping->tab_input_registers[addr + i] = v; break;
        }
    }
}

/* MBAP echo + (function | 0x80) + code. Built here rather than by libmodbus,
 * which adds 0x80 in a byte and wraps: FC 0x83 would be answered "03 01",
 * a normal FC 03 reply. A function code of 0x80 or more stays as it is. */
static int reply_exception(rig_supervision *sv, client *c, const uint8_t *req, int code)
{
    sv->stats.exceptions++;
    uint8_t rsp[MBAP_LEN + 2];
    memcpy(rsp, req, 4); /* transaction and protocol id */
    rsp[4] = 0;
    rsp[5] = 3;
    rsp[6] = req[6]; /* unit id */
    rsp[7] = (uint8_t)(req[MBAP_LEN] | 0x80u);
    rsp[8] = (uint8_t)code;
    return send(c->fd, rsp, sizeof rsp, MSG_NOSIGNAL) == (ssize_t)sizeof rsp ? 0 : -1;
}

static int reply_values(rig_supervision *sv, const uint8_t *req, int req_len)
{
    return modbus_reply(sv->ctx, req, req_len, sv->mapping) < 0 ? -1 : 0;
}

/* FC 01-04: from the register map. */
static int handle_read(rig_supervision *sv, client *c, const uint8_t *req, int req_len)
{
    static uint16_t values[MODBUS_MAX_READ_BITS];
    const uint8_t *pdu = req + MBAP_LEN;
    int function = pdu[0];
    if (req_len - MBAP_LEN != 5)
        return reply_exception(sv, c, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
    uint16_t addr = be16(pdu + 1), count = be16(pdu + 3);
    bool bits = function <= MODBUS_FC_READ_DISCRETE_INPUTS;
    if (count < 1 || count > (bits ? MODBUS_MAX_READ_BITS : MODBUS_MAX_READ_REGISTERS))
        return reply_exception(sv, c, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
    leveler_table table = table_of(function);
    leveler_reg_status st = leveler_regs_read(table, addr, count, values);
    if (st != LEVELER_REG_OK)
        return reply_exception(sv, c, req, exception_for(st));
    refresh_mapping(sv, table, addr, count, values);
    return reply_values(sv, req, req_len);
}

/* The values a write PDU carries, into values[]; false if the PDU is malformed. */
static bool write_values(const uint8_t *pdu, int pdu_len, uint16_t *values, uint16_t *count)
{
    int function = pdu[0];
    *count = 1;
    if (pdu_len < 5)
        return false;
    if (function == MODBUS_FC_WRITE_SINGLE_COIL) {
        uint16_t v = be16(pdu + 3);
        values[0] = v ? 1 : 0;
        return pdu_len == 5 && (v == 0xFF00 || v == 0x0000);
    }
    if (function == MODBUS_FC_WRITE_SINGLE_REGISTER) {
        values[0] = be16(pdu + 3);
        return pdu_len == 5;
    }
    *count = be16(pdu + 3);
    bool coils = function == MODBUS_FC_WRITE_MULTIPLE_COILS;
    int bytes = coils ? (*count + 7) / 8 : *count * 2;
    if (*count < 1 || *count > (coils ? MODBUS_MAX_WRITE_BITS : MODBUS_MAX_WRITE_REGISTERS) || pdu_len < 6 ||
        pdu[5] != bytes || pdu_len != 6 + pdu[5])
        return false;
    for (uint16_t i = 0; i < *count; i++)
        values[i] = coils ? (pdu[6 + i / 8] >> (i % 8)) & 1u : be16(pdu + 6 + 2 * i);
    return true;
}

/* FC 05, 06, 15, 16: through the firmware's validation, all or nothing. */
static int handle_write(rig_supervision *sv, client *c, const uint8_t *req, int req_len)
{
    static uint16_t values[MODBUS_MAX_WRITE_BITS];
    const uint8_t *pdu = req + MBAP_LEN;
    if (sv->read_only || !c->may_write) {
        sv->stats.refused_writes += !sv->read_only;
        return reply_exception(sv, c, req, MODBUS_EXCEPTION_ILLEGAL_FUNCTION);
    }
    uint16_t count;
    if (!write_values(pdu, req_len - MBAP_LEN, values, &count))
        return reply_exception(sv, c, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
    leveler_reg_status st = leveler_regs_write(table_of(pdu[0]), be16(pdu + 1), count, values, NULL);
    if (st != LEVELER_REG_OK)
        return reply_exception(sv, c, req, exception_for(st));
    /* Accepted: libmodbus builds the echo reply (it also stores the values
     * in the mapping, which is refreshed before every read anyway). */
    return reply_values(sv, req, req_len);
}

/* One whole request (MBAP + PDU). Returns -1 if the client must go. */
static int handle_request(rig_supervision *sv, client *c, const uint8_t *req, int req_len)
{
    modbus_set_socket(sv->ctx, c->fd);
    sv->stats.requests++;
    switch (req[MBAP_LEN]) {
    case MODBUS_FC_READ_COILS:
    case MODBUS_FC_READ_DISCRETE_INPUTS:
    case MODBUS_FC_READ_HOLDING_REGISTERS:
    case MODBUS_FC_READ_INPUT_REGISTERS:
        return handle_read(sv, c, req, req_len);
    case MODBUS_FC_WRITE_SINGLE_COIL:
    case MODBUS_FC_WRITE_SINGLE_REGISTER:
    case MODBUS_FC_WRITE_MULTIPLE_COILS:
    case MODBUS_FC_WRITE_MULTIPLE_REGISTERS:
        return handle_write(sv, c, req, req_len);
    default:
        return reply_exception(sv, c, req, MODBUS_EXCEPTION_ILLEGAL_FUNCTION);
    }
}

/* Handles up to FRAMES_PER_CLIENT_PER_CALL whole frames, already buffered
 * ones first, reading more while the socket has it. Returns -1 to drop. */
static int service_client(rig_supervision *sv, client *c, bool readable)
{
    int frames = 0;
    for (;;) {
        while (c->len >= MBAP_LEN && frames < FRAMES_PER_CLIENT_PER_CALL) {
            uint16_t protocol = be16(c->buf + 2), length = be16(c->buf + 4);
            if (protocol != 0 || length < 2 || length > 254 || (c->buf[MBAP_LEN] & 0x7Fu) == 0) {
                sv->stats.dropped_garbage++;
                return -1; /* not Modbus TCP (or function code 0 / 0x80, which have no exception reply) */
            }
            size_t frame = 6u + length;
            if (c->len < frame)
                break;
            if (handle_request(sv, c, c->buf, (int)frame) < 0)
                return -1;
            memmove(c->buf, c->buf + frame, c->len - frame);
            c->len -= frame;
            c->served++;
            frames++;
            c->last_request_ms = c->partial_since_ms = now_ms(); /* a remainder starts its own deadline */
        }
        if (!readable || frames >= FRAMES_PER_CLIENT_PER_CALL)
            return 0; /* frames left in buf are served on the next call, without new bytes */
        ssize_t n = recv(c->fd, c->buf + c->len, sizeof c->buf - c->len, 0);
        if (n == 0)
            return -1; /* peer closed */
        if (n < 0)
            return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? 0 : -1;
        if (c->len == 0)
            c->partial_since_ms = now_ms();
        c->len += (size_t)n;
    }
}

/* Slow clients (a request not whole within request_timeout_ms) and idle ones
 * (no complete request for idle_timeout_ms) go; single bytes keep nobody. */
static void drop_late_clients(rig_supervision *sv)
{
    uint64_t now = now_ms();
    for (uint32_t i = 0; i < sv->max_clients; i++) {
        client *c = &sv->clients[i];
        if (c->fd < 0 || has_frame(c))
            continue;
        if (c->len > 0 && now - c->partial_since_ms > sv->request_timeout_ms) {
            sv->stats.dropped_slow++;
            drop(c);
        } else if (now - c->last_request_ms > sv->idle_timeout_ms) {
            sv->stats.dropped_idle++;
            drop(c);
        }
    }
}

void rig_supervision_serve(rig_supervision *sv, int timeout_ms)
{
    struct pollfd fds[66];
    int owner[66];
    int n = 0;
    bool buffered = false; /* a client has whole frames waiting: do not sleep */
    /* Without room, the listening socket is left out: no busy loop on a backlog. */
    bool least_active, room = slot_for_new(sv, now_ms(), &least_active) != NULL;
    fds[n] = (struct pollfd){.fd = room ? sv->listen_fd : -1, .events = POLLIN};
    owner[n++] = -1;
    fds[n] = (struct pollfd){.fd = room ? sv->unix_fd : -1, .events = POLLIN};
    owner[n++] = -1;
    for (uint32_t i = 0; i < sv->max_clients; i++) {
        if (sv->clients[i].fd >= 0) {
            fds[n] = (struct pollfd){.fd = sv->clients[i].fd, .events = POLLIN};
            owner[n++] = (int)i;
            buffered = buffered || has_frame(&sv->clients[i]);
        }
    }
    int ready = poll(fds, (nfds_t)n, buffered || timeout_ms < 0 ? 0 : timeout_ms);
    for (int k = 2; k < n; k++) {
        client *c = &sv->clients[owner[k]];
        short ev = ready > 0 ? fds[k].revents : 0;
        if (ev == 0 && !has_frame(c))
            continue;
        if ((ev & (POLLERR | POLLNVAL)) || service_client(sv, c, (ev & (POLLIN | POLLHUP)) != 0) < 0)
            drop(c);
    }
    if (ready > 0 && (fds[1].revents & POLLIN))
        accept_clients(sv, sv->unix_fd);
    if (ready > 0 && (fds[0].revents & POLLIN))
        accept_clients(sv, sv->listen_fd);
    drop_late_clients(sv);
}

void rig_supervision_close(rig_supervision *sv)
{
    if (sv == NULL)
        return;
    for (uint32_t i = 0; sv->clients && i < sv->max_clients; i++)
        if (sv->clients[i].fd >= 0)
            drop(&sv->clients[i]);
    if (sv->listen_fd >= 0)
        close(sv->listen_fd);
    if (sv->unix_fd >= 0) {
        close(sv->unix_fd);
        unlink(sv->cfg->write_socket);
    }
    if (sv->mapping)
        modbus_mapping_free(sv->mapping);
    if (sv->ctx)
        modbus_free(sv->ctx); /* its socket was a client's, already closed */
    free(sv->clients);
    free(sv);
}
