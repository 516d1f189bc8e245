/*
 * leveler-mbaps: Modbus/TCP Security (mbaps) in front of leveler-rig, with
 * write rights from the client certificate's role.
 *
 *   leveler-mbaps --config rig.ini
 *
 * TLS 1.2 or newer (OpenSSL) with mutual authentication: a client
 * certificate from [mbaps] ca is required, checked against the CRL in
 * [mbaps] crl (a revoked certificate gets no connection). The role is the
 * value (UTF8String) of the certificate's Modbus/TCP Security role extension,
 * OID 1.3.6.1.4.1.50316.802.1. Roles listed in [mbaps] write_roles may read
 * and write; any other role, or none (or the extension twice), reads only:
 * every function code other than 01-04 is answered here with exception 01
 * (ILLEGAL FUNCTION) and never reaches the rig.
 *
 * Each connection is served by its own process (a slow handshake holds up
 * nobody), which talks to the rig over [supervision] write_socket: a Unix
 * socket only this program's user or group may open, so write rights never
 * come from a source address another local process could take. (stunnel
 * cannot be used for this: it passes on neither the certificate nor its
 * extensions.)
 */
#define _GNU_SOURCE
#include <arpa/inet.h>
#include <errno.h>
#include <netdb.h>
#include <poll.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>

#include "cli.h"
#include "mbap.h"
#include "rig_config.h"

#define ROLE_OID "1.3.6.1.4.1.50316.802.1"
#define HANDSHAKE_TIMEOUT_S 10

static volatile sig_atomic_t stop_requested;

static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

static const char *ssl_error(void)
{
    static char text[256];
    unsigned long e = ERR_get_error();
    if (e == 0)
        return "connection closed";
    ERR_error_string_n(e, text, sizeof text);
    return text;
}

/* The server's TLS context: certificate, key, client CA, CRL. NULL after a message naming the key. */
static SSL_CTX *tls_context(const char *path, const rig_config *cfg)
{
    SSL_CTX *ctx = SSL_CTX_new(TLS_server_method());
    const char *bad = NULL, *file = NULL;
    if (ctx == NULL || SSL_CTX_set_min_proto_version(ctx, TLS1_2_VERSION) != 1)
        bad = "TLS", file = "";
    else if (SSL_CTX_use_certificate_chain_file(ctx, cfg->mbaps_cert) != 1)
        bad = "cert", file = cfg->mbaps_cert;
    else if (SSL_CTX_use_PrivateKey_file(ctx, cfg->mbaps_key, SSL_FILETYPE_PEM) != 1 ||
             SSL_CTX_check_private_key(ctx) != 1)
        bad = "key", file = cfg->mbaps_key;
    else if (SSL_CTX_load_verify_locations(ctx, cfg->mbaps_ca, NULL) != 1)
        bad = "ca", file = cfg->mbaps_ca;
    if (bad == NULL && cfg->mbaps_crl[0]) {
        X509_STORE *store = SSL_CTX_get_cert_store(ctx);
        X509_LOOKUP *lookup = X509_STORE_add_lookup(store, X509_LOOKUP_file());
        if (lookup == NULL || X509_load_crl_file(lookup, cfg->mbaps_crl, X509_FILETYPE_PEM) < 1)
            bad = "crl", file = cfg->mbaps_crl;
        else
            X509_STORE_set_flags(store, X509_V_FLAG_CRL_CHECK);
    }
    if (bad != NULL) {
        fprintf(stderr, "leveler-mbaps: %s: [mbaps] %s: %s: %s\n", path, bad, file, ssl_error());
        SSL_CTX_free(ctx);
        return NULL;
    }
    SSL_CTX_set_verify(ctx, SSL_VERIFY_PEER | SSL_VERIFY_FAIL_IF_NO_PEER_CERT, NULL);
    return ctx;
}

/* The role extension's text into role (cap bytes); false if there is none,
 * more than one, or it is not a UTF8String. */
static bool cert_role(X509 *cert, char *role, size_t cap)
{
    ASN1_OBJECT *oid = OBJ_txt2obj(ROLE_OID, 1);
    int at = oid ? X509_get_ext_by_OBJ(cert, oid, -1) : -1;
    bool ok = at >= 0 && X509_get_ext_by_OBJ(cert, oid, at) < 0;
    ASN1_OBJECT_free(oid);
    if (!ok)
        return false;
    ASN1_OCTET_STRING *data = X509_EXTENSION_get_data(X509_get_ext(cert, at));
    const unsigned char *p = ASN1_STRING_get0_data(data);
    ASN1_UTF8STRING *text = d2i_ASN1_UTF8STRING(NULL, &p, ASN1_STRING_length(data));
    ok = text != NULL && (size_t)ASN1_STRING_length(text) < cap &&
         memchr(ASN1_STRING_get0_data(text), 0, (size_t)ASN1_STRING_length(text)) == NULL;
    if (ok) {
        memcpy(role, ASN1_STRING_get0_data(text), (size_t)ASN1_STRING_length(text));
        role[ASN1_STRING_length(text)] = '\0';
    }
    ASN1_UTF8STRING_free(text);
    return ok;
}

static bool role_may_write(const rig_config *cfg, const char *role)
{
    for (uint32_t i = 0; i < cfg->mbaps_write_role_count; i++)
        if (!strcmp(role, cfg->mbaps_write_roles[i]))
            return true;
    return false;
}

static int connect_rig(const char *socket_path)
{
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", socket_path);
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd >= 0 && connect(fd, (struct sockaddr *)&sa, sizeof sa) != 0) {
        close(fd);
        fd = -1;
    }
    return fd;
}

static int ssl_write_all(SSL *ssl, const uint8_t *p, size_t n)
{
    size_t done = 0;
    return SSL_write_ex(ssl, p, n, &done) == 1 && done == n ? 0 : -1;
}

static int write_all(int fd, const uint8_t *p, size_t n)
{
    while (n > 0) {
        ssize_t k = write(fd, p, n);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            return -1;
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

/* Whole frames from the client: reads (01-04) to the rig, anything else too
 * if the role may write, else exception 01 from here. -1: close. */
static int forward_frames(SSL *ssl, int rig_fd, bool may_write, uint8_t *buf, size_t *len)
{
    for (;;) {
        int whole = mbap_frame_length(buf, *len);
        if (whole <= 0)
            return whole; /* 0: wait for the rest; -1: not Modbus TCP */
        size_t frame = (size_t)whole;
        uint8_t function = buf[MBAP_HEADER_LEN];
        if (may_write || (function >= 1 && function <= 4)) {
            if (write_all(rig_fd, buf, frame) != 0)
                return -1;
        } else {
            uint8_t rsp[MBAP_HEADER_LEN + 2];
            size_t n = mbap_exception_response(buf, LEVELER_PDU_ILLEGAL_FUNCTION, rsp);
            if (ssl_write_all(ssl, rsp, n) != 0)
                return -1;
        }
        memmove(buf, buf + frame, *len - frame);
        *len -= frame;
    }
}

/* Relays until either side closes. */
static void relay(SSL *ssl, int tls_fd, int rig_fd, bool may_write)
{
    uint8_t in[2 * MBAP_FRAME_MAX], out[4096];
    size_t in_len = 0;
    while (!stop_requested) {
        struct pollfd p[2] = {{.fd = tls_fd, .events = POLLIN}, {.fd = rig_fd, .events = POLLIN}};
        if (SSL_pending(ssl) == 0 && poll(p, 2, -1) < 0 && errno != EINTR)
            return;
        if (SSL_pending(ssl) > 0 || (p[0].revents & (POLLIN | POLLHUP | POLLERR))) {
            size_t n = 0;
            if (SSL_read_ex(ssl, in + in_len, sizeof in - in_len, &n) != 1) {
                int e = SSL_get_error(ssl, 0);
                if (e != SSL_ERROR_WANT_READ && e != SSL_ERROR_WANT_WRITE)
                    return;
            }
            in_len += n;
            if (forward_frames(ssl, rig_fd, may_write, in, &in_len) != 0)
                return;
        }
        if (p[1].revents & (POLLIN | POLLHUP | POLLERR)) {
            ssize_t n = read(rig_fd, out, sizeof out);
            if (n <= 0 || ssl_write_all(ssl, out, (size_t)n) != 0)
                return;
        }
    }
}

/* One client, in its own process. */
static void serve_client(SSL_CTX *ctx, int fd, const rig_config *cfg, const char *peer)
{
    SSL *ssl = SSL_new(ctx);
    alarm(HANDSHAKE_TIMEOUT_S);
    if (ssl == NULL || SSL_set_fd(ssl, fd) != 1 || SSL_accept(ssl) != 1) {
        fprintf(stderr, "leveler-mbaps: %s: refused: %s\n", peer, ssl_error());
        return;
    }
    alarm(0);
    X509 *cert = SSL_get1_peer_certificate(ssl);
    char role[64] = "", subject[256] = "?";
    bool has_role = cert && cert_role(cert, role, sizeof role);
    if (cert)
        X509_NAME_oneline(X509_get_subject_name(cert), subject, sizeof subject);
    X509_free(cert);
    bool may_write = has_role && role_may_write(cfg, role);
    int rig_fd = connect_rig(cfg->write_socket);
    fprintf(stderr, "leveler-mbaps: %s: %s, role %s: %s%s\n", peer, subject, has_role ? role : "(none)",
            may_write ? "reads and writes" : "reads only", rig_fd < 0 ? "; the rig does not answer" : "");
    if (rig_fd >= 0) {
        relay(ssl, fd, rig_fd, may_write);
        close(rig_fd);
    }
    SSL_shutdown(ssl);
    SSL_free(ssl);
}

static int listen_tcp(const rig_config *cfg, const char *path)
{
    struct addrinfo hints = {.ai_flags = AI_PASSIVE | AI_NUMERICHOST | AI_NUMERICSERV, .ai_socktype = SOCK_STREAM};
    struct addrinfo *ai = NULL;
    char service[8];
    snprintf(service, sizeof service, "%u", cfg->mbaps_port);
    int one = 1, fd = -1;
    if (getaddrinfo(cfg->mbaps_address, service, &hints, &ai) == 0)
        fd = socket(ai->ai_family, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0 || setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0 ||
        bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || listen(fd, 16) != 0) {
        fprintf(stderr, "leveler-mbaps: %s: [mbaps] address/port: cannot listen on %s port %u: %s\n", path,
                cfg->mbaps_address, cfg->mbaps_port, strerror(errno));
        if (fd >= 0)
            close(fd);
        fd = -1;
    }
    if (ai)
        freeaddrinfo(ai);
    return fd;
}

static unsigned bound_port(int fd)
{
    struct sockaddr_storage sa;
    socklen_t len = sizeof sa;
    getsockname(fd, (struct sockaddr *)&sa, &len);
    return ntohs(sa.ss_family == AF_INET6 ? ((struct sockaddr_in6 *)&sa)->sin6_port
                                          : ((struct sockaddr_in *)&sa)->sin_port);
}

static void write_port_file(unsigned port, const char *file)
{
    char tmp[RIG_TEXT_MAX + 8];
    snprintf(tmp, sizeof tmp, "%s.tmp", file);
    FILE *f = fopen(tmp, "w");
    if (f == NULL || fprintf(f, "%u\n", port) < 0 || fclose(f) != 0 || rename(tmp, file) != 0)
        fprintf(stderr, "leveler-mbaps: [mbaps] port_file %s: %s\n", file, strerror(errno));
}

/* What the program needs from the config; a message naming the key otherwise. */
static int check_config(const char *path, const rig_config *cfg)
{
    const char *missing = !cfg->write_socket[0] ? "[supervision] write_socket"
                          : !cfg->mbaps_cert[0] ? "[mbaps] cert"
                          : !cfg->mbaps_key[0]  ? "[mbaps] key"
                          : !cfg->mbaps_ca[0]   ? "[mbaps] ca"
                                                : NULL;
    if (missing)
        fprintf(stderr, "leveler-mbaps: %s: %s: required\n", path, missing);
    return missing ? -1 : 0;
}

static void accept_loop(SSL_CTX *ctx, int lfd, const rig_config *cfg)
{
    while (!stop_requested) {
        struct sockaddr_storage sa;
        socklen_t len = sizeof sa;
        int fd = accept4(lfd, (struct sockaddr *)&sa, &len, SOCK_CLOEXEC);
        if (fd < 0)
            continue;
        char host[64] = "?", port[8] = "?";
        getnameinfo((struct sockaddr *)&sa, len, host, sizeof host, port, sizeof port, NI_NUMERICHOST | NI_NUMERICSERV);
        char peer[80];
        snprintf(peer, sizeof peer, "%s port %s", host, port);
        pid_t pid = fork();
        if (pid == 0) {
            close(lfd);
            signal(SIGTERM, SIG_DFL);
            serve_client(ctx, fd, cfg, peer);
            _exit(0);
        }
        if (pid < 0)
            fprintf(stderr, "leveler-mbaps: %s: fork: %s\n", peer, strerror(errno));
        close(fd);
    }
}

enum { OPT_CONFIG = 0x100 };

static const cli_option mbaps_options[] = {
    {"config", OPT_CONFIG, "FILE", "the rig's INI file: its [mbaps] and [supervision] write_socket (boards/linux-rig/rig.ini)", 1},
    {NULL, 0, NULL, NULL, 0},
};

static const cli_spec mbaps_cli = {
    .prog = "leveler-mbaps",
    .usage = "--config FILE",
    .about = "Modbus/TCP Security (TLS, client certificates, roles) in front of leveler-rig.",
    .opts = mbaps_options,
};

static int mbaps_option(void *user, int key, const char *v)
{
    (void)key;
    *(const char **)user = v;
    return 0;
}

int main(int argc, char **argv)
{
    const char *config = NULL;
    int prc = cli_parse(&mbaps_cli, argc, argv, mbaps_option, &config, NULL);
    if (prc != CLI_CONTINUE)
        return prc;
    static rig_config cfg;
    char err[512];
    rig_config_defaults(&cfg);
    if (rig_config_load(config, &cfg, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-mbaps: %s\n", err);
        return 2;
    }
    if (check_config(config, &cfg) != 0)
        return 2;
    SSL_CTX *ctx = tls_context(config, &cfg);
    int lfd = ctx ? listen_tcp(&cfg, config) : -1;
    if (lfd < 0)
        return 1;
    if (cfg.mbaps_port_file[0])
        write_port_file(bound_port(lfd), cfg.mbaps_port_file);
    struct sigaction sa = {.sa_handler = on_signal};
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    signal(SIGCHLD, SIG_IGN); /* children reaped by the kernel */
    signal(SIGPIPE, SIG_IGN);
    fprintf(stderr, "leveler-mbaps: on %s port %u, writes for role%s", cfg.mbaps_address, bound_port(lfd),
            cfg.mbaps_write_role_count == 1 ? "" : "s");
    for (uint32_t i = 0; i < cfg.mbaps_write_role_count; i++)
        fprintf(stderr, " %s", cfg.mbaps_write_roles[i]);
    fprintf(stderr, "%s\n", cfg.mbaps_crl[0] ? "; CRL checked" : "; no CRL");
    accept_loop(ctx, lfd, &cfg);
    close(lfd);
    SSL_CTX_free(ctx);
    return 0;
}
