#define _GNU_SOURCE /* accept4 */
#include "supervision.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
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
    uint64_t last_ms;
} client;

struct rig_supervision {
    modbus_t *ctx;               /* reply builder; its socket is set per client */
    modbus_mapping_t *mapping;   /* refreshed from the register map before each read */
    int listen_fd;
    uint16_t port;
    bool read_only;
    uint32_t idle_timeout_ms;
    uint32_t max_clients;
    client *clients;
    rig_supervision_stats stats;
};

static uint64_t now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000u + (uint64_t)t.tv_nsec / 1000000u;
}

rig_supervision *rig_supervision_open(const rig_config *cfg, char *err, size_t err_len)
{
    rig_supervision *sv = calloc(1, sizeof *sv);
    if (sv == NULL) {
        snprintf(err, err_len, "supervision: out of memory");
        return NULL;
    }
    sv->listen_fd = -1;
    sv->read_only = cfg->read_only;
    sv->idle_timeout_ms = cfg->idle_timeout_ms;
    sv->max_clients = cfg->max_clients;
    sv->clients = calloc(cfg->max_clients, sizeof *sv->clients);
    for (uint32_t i = 0; sv->clients && i < cfg->max_clients; i++)
        sv->clients[i].fd = -1;
    sv->ctx = modbus_new_tcp(cfg->supervision_address, cfg->supervision_port);
    sv->mapping = modbus_mapping_new(leveler_regs_table_size(LEVELER_TABLE_COIL),
                                     leveler_regs_table_size(LEVELER_TABLE_DISCRETE_INPUT),
                                     leveler_regs_table_size(LEVELER_TABLE_HOLDING_REGISTER),
                                     leveler_regs_table_size(LEVELER_TABLE_INPUT_REGISTER));
    if (sv->clients == NULL || sv->ctx == NULL || sv->mapping == NULL) {
        snprintf(err, err_len, "supervision: [supervision] address '%s': %s", cfg->supervision_address,
                 modbus_strerror(errno));
        rig_supervision_close(sv);
        return NULL;
    }
    sv->listen_fd = modbus_tcp_listen(sv->ctx, 8);
    if (sv->listen_fd < 0) {
        snprintf(err, err_len, "supervision: [supervision] address/port: cannot listen on %s:%u: %s",
                 cfg->supervision_address, cfg->supervision_port, modbus_strerror(errno));
        rig_supervision_close(sv);
        return NULL;
    }
    /* accept_clients() drains the backlog until EAGAIN: never block the tick. */
    fcntl(sv->listen_fd, F_SETFL, fcntl(sv->listen_fd, F_GETFL) | O_NONBLOCK);
    struct sockaddr_in addr;
    socklen_t alen = sizeof addr;
    getsockname(sv->listen_fd, (struct sockaddr *)&addr, &alen);
    sv->port = ntohs(addr.sin_port);
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

static void drop(client *c)
{
    close(c->fd);
    c->fd = -1;
    c->len = 0;
}

static void accept_clients(rig_supervision *sv)
{
    for (int n = 0; n < 8; n++) {
        int fd = accept4(sv->listen_fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0)
            return;
        client *slot = NULL;
        for (uint32_t i = 0; i < sv->max_clients; i++)
            if (sv->clients[i].fd < 0) {
                slot = &sv->clients[i];
                break;
            }
        if (slot == NULL) {
            close(fd);
            sv->stats.refused_full++;
            continue;
        }
        slot->fd = fd;
        slot->len = 0;
        slot->last_ms = now_ms();
        sv->stats.accepted++;
    }
}

static uint16_t be16(const uint8_t *p)
{
    return (uint16_t)((p[0] << 8) | p[1]);
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

/* One whole request (MBAP + PDU). Returns -1 if the client must go. */
static int handle_request(rig_supervision *sv, client *c, const uint8_t *req, int req_len)
{
    modbus_set_socket(sv->ctx, c->fd);
    sv->stats.requests++;
    const uint8_t *pdu = req + MBAP_LEN;
    int pdu_len = req_len - MBAP_LEN;
    int function = pdu[0];
    int rc;
    static uint16_t values[MODBUS_MAX_READ_BITS];

    switch (function) {
    case MODBUS_FC_READ_COILS:
    case MODBUS_FC_READ_DISCRETE_INPUTS:
    case MODBUS_FC_READ_HOLDING_REGISTERS:
    case MODBUS_FC_READ_INPUT_REGISTERS: {
        if (pdu_len != 5)
            goto bad_value;
        uint16_t addr = be16(pdu + 1), count = be16(pdu + 3);
        bool bits = function <= MODBUS_FC_READ_DISCRETE_INPUTS;
        if (count < 1 || count > (bits ? MODBUS_MAX_READ_BITS : MODBUS_MAX_READ_REGISTERS))
            goto bad_value;
        leveler_table table = table_of(function);
        leveler_reg_status st = leveler_regs_read(table, addr, count, values);
        if (st != LEVELER_REG_OK) {
            sv->stats.exceptions++;
            return modbus_reply_exception(sv->ctx, req, (unsigned)exception_for(st)) < 0 ? -1 : 0;
        }
        refresh_mapping(sv, table, addr, count, values);
        rc = modbus_reply(sv->ctx, req, req_len, sv->mapping);
        return rc < 0 ? -1 : 0;
    }
    case MODBUS_FC_WRITE_SINGLE_COIL:
    case MODBUS_FC_WRITE_SINGLE_REGISTER:
    case MODBUS_FC_WRITE_MULTIPLE_COILS:
    case MODBUS_FC_WRITE_MULTIPLE_REGISTERS: {
        if (sv->read_only) {
            sv->stats.exceptions++;
            return modbus_reply_exception(sv->ctx, req, MODBUS_EXCEPTION_ILLEGAL_FUNCTION) < 0 ? -1 : 0;
        }
        if (pdu_len < 5)
            goto bad_value;
        uint16_t addr = be16(pdu + 1), count = 1;
        if (function == MODBUS_FC_WRITE_SINGLE_COIL) {
            uint16_t v = be16(pdu + 3);
            if (pdu_len != 5 || (v != 0xFF00 && v != 0x0000))
                goto bad_value;
            values[0] = v ? 1 : 0;
        } else if (function == MODBUS_FC_WRITE_SINGLE_REGISTER) {
            if (pdu_len != 5)
                goto bad_value;
            values[0] = be16(pdu + 3);
        } else if (function == MODBUS_FC_WRITE_MULTIPLE_COILS) {
            count = be16(pdu + 3);
            if (count < 1 || count > MODBUS_MAX_WRITE_BITS || pdu_len < 6 || pdu[5] != (count + 7) / 8 ||
                pdu_len != 6 + pdu[5])
                goto bad_value;
            for (uint16_t i = 0; i < count; i++)
                values[i] = (pdu[6 + i / 8] >> (i % 8)) & 1u;
        } else {
            count = be16(pdu + 3);
            if (count < 1 || count > MODBUS_MAX_WRITE_REGISTERS || pdu_len < 6 || pdu[5] != count * 2 ||
                pdu_len != 6 + pdu[5])
                goto bad_value;
            for (uint16_t i = 0; i < count; i++)
                values[i] = be16(pdu + 6 + 2 * i);
        }
        /* Through the firmware's validation, all or nothing. */
        leveler_reg_status st = leveler_regs_write(table_of(function), addr, count, values, NULL);
        if (st != LEVELER_REG_OK) {
            sv->stats.exceptions++;
            return modbus_reply_exception(sv->ctx, req, (unsigned)exception_for(st)) < 0 ? -1 : 0;
        }
        /* Accepted: libmodbus builds the echo reply (it also stores the values
         * in the mapping, which is refreshed before every read anyway). */
        rc = modbus_reply(sv->ctx, req, req_len, sv->mapping);
        return rc < 0 ? -1 : 0;
    }
    default:
        sv->stats.exceptions++;
        return modbus_reply_exception(sv->ctx, req, MODBUS_EXCEPTION_ILLEGAL_FUNCTION) < 0 ? -1 : 0;
    }
bad_value:
    sv->stats.exceptions++;
    return modbus_reply_exception(sv->ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE) < 0 ? -1 : 0;
}

/* Reads what the socket has, handles whole frames. Returns -1 to drop. */
static int service_client(rig_supervision *sv, client *c)
{
    for (int frames = 0; frames < FRAMES_PER_CLIENT_PER_CALL;) {
        ssize_t n = recv(c->fd, c->buf + c->len, sizeof c->buf - c->len, 0);
        if (n == 0)
            return -1; /* peer closed */
        if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)
            return -1;
        if (n > 0) {
            c->len += (size_t)n;
            c->last_ms = now_ms();
        }
        bool progressed = false;
        while (c->len >= MBAP_LEN && frames < FRAMES_PER_CLIENT_PER_CALL) {
            uint16_t protocol = be16(c->buf + 2), length = be16(c->buf + 4);
            if (protocol != 0 || length < 2 || length > 254) {
                sv->stats.dropped_garbage++;
                return -1; /* not Modbus TCP: no way to find the next frame */
            }
            size_t frame = 6u + length;
            if (c->len < frame)
                break;
            if (handle_request(sv, c, c->buf, (int)frame) < 0)
                return -1;
            memmove(c->buf, c->buf + frame, c->len - frame);
            c->len -= frame;
            frames++;
            progressed = true;
        }
        if (n <= 0 || !progressed)
            return 0;
    }
    return 0;
}

void rig_supervision_serve(rig_supervision *sv, int timeout_ms)
{
    struct pollfd fds[65];
    int owner[65];
    int n = 0;
    fds[n] = (struct pollfd){.fd = sv->listen_fd, .events = POLLIN};
    owner[n++] = -1;
    for (uint32_t i = 0; i < sv->max_clients; i++) {
        if (sv->clients[i].fd >= 0) {
            fds[n] = (struct pollfd){.fd = sv->clients[i].fd, .events = POLLIN};
            owner[n++] = (int)i;
        }
    }
    int ready = poll(fds, (nfds_t)n, timeout_ms < 0 ? 0 : timeout_ms);
    if (ready > 0) {
        for (int k = 1; k < n; k++) {
            if (fds[k].revents == 0)
                continue;
            client *c = &sv->clients[owner[k]];
            if ((fds[k].revents & (POLLERR | POLLNVAL)) || service_client(sv, c) < 0)
                drop(c);
        }
        if (fds[0].revents & POLLIN)
            accept_clients(sv);
    }
    uint64_t now = now_ms();
    for (uint32_t i = 0; i < sv->max_clients; i++) {
        client *c = &sv->clients[i];
        if (c->fd >= 0 && now - c->last_ms > sv->idle_timeout_ms) {
            sv->stats.dropped_idle++;
            drop(c);
        }
    }
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
    if (sv->mapping)
        modbus_mapping_free(sv->mapping);
    if (sv->ctx)
        modbus_free(sv->ctx); /* its socket was a client's, already closed */
    free(sv->clients);
    free(sv);
}
