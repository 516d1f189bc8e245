#define _GNU_SOURCE /* accept4 */
#include "modbus_tcp_server.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
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

#include "leveler/modbus_pdu.h"
#include "mbap.h"

#define FRAMES_PER_CLIENT_PER_CALL 8

typedef struct {
    int fd;
    uint8_t buf[MBAP_FRAME_MAX];
    size_t len;
    uint64_t last_request_ms; /* last complete request (or the connect): the idle timer */
    uint64_t partial_since_ms; /* first byte of the request in buf: the request deadline */
    uint32_t served;           /* complete requests handled */
    bool may_write;            /* its address is in [supervision] writers (or there is no list) */
} client;

struct rig_modbus_tcp_server {
    int listen_fd;
    int unix_fd;                 /* [supervision] write_socket, or -1 */
    uint16_t port;
    bool read_only;
    uint32_t idle_timeout_ms;
    uint32_t request_timeout_ms;
    uint32_t max_clients;
    const rig_config *cfg;
    client *clients;
    rig_modbus_tcp_server_stats stats;
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
        snprintf(err, err_len, "modbus tcp server: [supervision] address '%s': %s", address, gai_strerror(rc));
        return -1;
    }
    int fd = socket(ai->ai_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    int one = 1;
    if (fd < 0 || setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0 ||
        bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || listen(fd, 16) != 0) {
        snprintf(err, err_len, "modbus tcp server: [supervision] address/port: cannot listen on %s port %u: %s", address,
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
        snprintf(err, err_len, "modbus tcp server: [supervision] write_socket: '%s' longer than %zu bytes", path,
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
        snprintf(err, err_len, "modbus tcp server: [supervision] write_socket: cannot listen on %s: %s", path,
                 strerror(errno));
        if (fd >= 0)
            close(fd);
        return -1;
    }
    return fd;
}

rig_modbus_tcp_server *rig_modbus_tcp_server_open(const rig_config *cfg, char *err, size_t err_len)
{
    rig_modbus_tcp_server *srv = calloc(1, sizeof *srv);
    if (srv == NULL) {
        snprintf(err, err_len, "modbus tcp server: out of memory");
        return NULL;
    }
    srv->cfg = cfg;
    srv->read_only = cfg->read_only;
    srv->idle_timeout_ms = cfg->idle_timeout_ms;
    srv->request_timeout_ms = cfg->request_timeout_ms;
    srv->max_clients = cfg->max_clients;
    srv->clients = calloc(cfg->max_clients, sizeof *srv->clients);
    for (uint32_t i = 0; srv->clients && i < cfg->max_clients; i++)
        srv->clients[i].fd = -1;
    srv->listen_fd = -1;
    srv->unix_fd = -1;
    if (srv->clients == NULL) {
        snprintf(err, err_len, "modbus tcp server: out of memory");
        rig_modbus_tcp_server_close(srv);
        return NULL;
    }
    srv->listen_fd = listen_on(cfg->supervision_address, cfg->supervision_port, &srv->port, err, err_len);
    if (srv->listen_fd >= 0 && cfg->write_socket[0])
        srv->unix_fd = listen_on_unix(cfg->write_socket, err, err_len);
    if (srv->listen_fd < 0 || (cfg->write_socket[0] && srv->unix_fd < 0)) {
        rig_modbus_tcp_server_close(srv);
        return NULL;
    }
    return srv;
}

uint16_t rig_modbus_tcp_server_port(const rig_modbus_tcp_server *srv)
{
    return srv->port;
}

rig_modbus_tcp_server_stats rig_modbus_tcp_server_get_stats(const rig_modbus_tcp_server *srv)
{
    return srv->stats;
}

static void drop(client *c)
{
    close(c->fd);
    c->fd = -1;
    c->len = 0;
}

/* The peer's address as [supervision] writers spells it (IPv4-mapped IPv6 as IPv4). */
static bool peer_may_write(const rig_modbus_tcp_server *srv, int fd)
{
    if (srv->cfg->writer_count == 0)
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
    for (uint32_t i = 0; i < srv->cfg->writer_count; i++)
        if (!strcmp(text, srv->cfg->writers[i]))
            return true;
    return false;
}

/* Something to do without new bytes: a whole request, or bytes that are not
 * Modbus TCP (the client is dropped). */
static bool has_frame(const client *c)
{
    return mbap_frame_length(c->buf, c->len) != 0;
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
static client *slot_for_new(rig_modbus_tcp_server *srv, uint64_t now, bool *least_active)
{
    client *victim = NULL, *fallback = NULL;
    *least_active = false;
    for (uint32_t i = 0; i < srv->max_clients; i++) {
        client *c = &srv->clients[i];
        if (c->fd < 0)
            return c;
        uint64_t quiet = now - c->last_request_ms;
        if (has_frame(c) || quiet < NEW_CLIENT_GRACE_MS)
            continue;
        if (c->len == 0 && (fallback == NULL || c->last_request_ms < fallback->last_request_ms))
            fallback = c;
        if (quiet < (c->served ? srv->request_timeout_ms : NEW_CLIENT_GRACE_MS))
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
static void accept_clients(rig_modbus_tcp_server *srv, int listen_fd)
{
    for (int n = 0; n < 8; n++) {
        uint64_t now = now_ms();
        bool least_active;
        client *slot = slot_for_new(srv, now, &least_active);
        if (slot == NULL)
            return;
        int fd = accept4(listen_fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0)
            return;
        if (slot->fd >= 0) {
            drop(slot);
            srv->stats.evicted++;
            srv->stats.evicted_active += least_active;
        }
        /* With a write_socket only its clients write; else [supervision] writers decides. */
        bool may_write = listen_fd == srv->unix_fd || (srv->unix_fd < 0 && peer_may_write(srv, fd));
        *slot = (client){.fd = fd, .last_request_ms = now, .may_write = may_write};
        srv->stats.accepted++;
    }
}

static bool is_write(uint8_t function)
{
    return function == 0x05 || function == 0x06 || function == 0x0F || function == 0x10;
}

/* One whole request (MBAP + PDU): the rig's write policy (read_only, writers,
 * write_socket), then the PDU server. Returns -1 if the client must go. */
static int handle_request(rig_modbus_tcp_server *srv, client *c, const uint8_t *req, size_t req_len)
{
    uint8_t rsp[MBAP_FRAME_MAX];
    uint8_t *rsp_pdu = rsp + MBAP_HEADER_LEN;
    const uint8_t function = req[MBAP_HEADER_LEN];
    size_t pdu_len;
    srv->stats.requests++;
    if (is_write(function) && (srv->read_only || !c->may_write)) {
        srv->stats.refused_writes += !srv->read_only;
        pdu_len = leveler_modbus_pdu_exception(function, LEVELER_PDU_ILLEGAL_FUNCTION, rsp_pdu);
    } else {
        pdu_len = leveler_modbus_pdu_serve(req + MBAP_HEADER_LEN, req_len - MBAP_HEADER_LEN, rsp_pdu,
                                           LEVELER_PDU_MAX);
    }
    if (pdu_len == 0)
        return -1; /* unreachable: mbap_frame_length() refuses function codes without a reply */
    srv->stats.exceptions += (rsp_pdu[0] & 0x80u) != 0;
    size_t n = mbap_wrap_response(req, rsp, pdu_len);
    return send(c->fd, rsp, n, MSG_NOSIGNAL) == (ssize_t)n ? 0 : -1;
}

/* Handles up to FRAMES_PER_CLIENT_PER_CALL whole frames, already buffered
 * ones first, reading more while the socket has it. Returns -1 to drop. */
static int service_client(rig_modbus_tcp_server *srv, client *c, bool readable)
{
    int frames = 0;
    for (;;) {
        while (frames < FRAMES_PER_CLIENT_PER_CALL) {
            int whole = mbap_frame_length(c->buf, c->len);
            if (whole < 0) {
                srv->stats.dropped_garbage++;
                return -1; /* not Modbus TCP (or function code 0 / 0x80, which have no exception reply) */
            }
            if (whole == 0)
                break;
            size_t frame = (size_t)whole;
            if (handle_request(srv, c, c->buf, frame) < 0)
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
static void drop_late_clients(rig_modbus_tcp_server *srv)
{
    uint64_t now = now_ms();
    for (uint32_t i = 0; i < srv->max_clients; i++) {
        client *c = &srv->clients[i];
        if (c->fd < 0 || has_frame(c))
            continue;
        if (c->len > 0 && now - c->partial_since_ms > srv->request_timeout_ms) {
            srv->stats.dropped_slow++;
            drop(c);
        } else if (now - c->last_request_ms > srv->idle_timeout_ms) {
            srv->stats.dropped_idle++;
            drop(c);
        }
    }
}

void rig_modbus_tcp_server_serve(rig_modbus_tcp_server *srv, int timeout_ms)
{
    struct pollfd fds[66];
    int owner[66];
    int n = 0;
    bool buffered = false; /* a client has whole frames waiting: do not sleep */
    /* Without room, the listening socket is left out: no busy loop on a backlog. */
    bool least_active, room = slot_for_new(srv, now_ms(), &least_active) != NULL;
    fds[n] = (struct pollfd){.fd = room ? srv->listen_fd : -1, .events = POLLIN};
    owner[n++] = -1;
    fds[n] = (struct pollfd){.fd = room ? srv->unix_fd : -1, .events = POLLIN};
    owner[n++] = -1;
    for (uint32_t i = 0; i < srv->max_clients; i++) {
        if (srv->clients[i].fd >= 0) {
            fds[n] = (struct pollfd){.fd = srv->clients[i].fd, .events = POLLIN};
            owner[n++] = (int)i;
            buffered = buffered || has_frame(&srv->clients[i]);
        }
    }
    int ready = poll(fds, (nfds_t)n, buffered || timeout_ms < 0 ? 0 : timeout_ms);
    for (int k = 2; k < n; k++) {
        client *c = &srv->clients[owner[k]];
        short ev = ready > 0 ? fds[k].revents : 0;
        if (ev == 0 && !has_frame(c))
            continue;
        if ((ev & (POLLERR | POLLNVAL)) || service_client(srv, c, (ev & (POLLIN | POLLHUP)) != 0) < 0)
            drop(c);
    }
    if (ready > 0 && (fds[1].revents & POLLIN))
        accept_clients(srv, srv->unix_fd);
    if (ready > 0 && (fds[0].revents & POLLIN))
        accept_clients(srv, srv->listen_fd);
    drop_late_clients(srv);
}

void rig_modbus_tcp_server_close(rig_modbus_tcp_server *srv)
{
    if (srv == NULL)
        return;
    for (uint32_t i = 0; srv->clients && i < srv->max_clients; i++)
        if (srv->clients[i].fd >= 0)
            drop(&srv->clients[i]);
    if (srv->listen_fd >= 0)
        close(srv->listen_fd);
    if (srv->unix_fd >= 0) {
        close(srv->unix_fd);
        unlink(srv->cfg->write_socket);
    }
    free(srv->clients);
    free(srv);
}
