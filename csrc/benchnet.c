/*
 * Benchmark peers over loopback TCP, with CPU pinning:
 *
 *  - rc_pingpong_*: a persistent C ping-pong (echo thread + the calling thread) whose round
 *    trips are run in caller-sized chunks, so a benchmark can be interrupted between chunks;
 *    each end can be pinned to a CPU, which is what makes the floor mean the same on every
 *    run (on a 2-vCPU VM: ~4 us with both ends on one CPU, ~70 us across CPUs);
 *  - rc_responder_*: a minimal server that answers every complete ARCOS frame whose payload
 *    is in a table with a canned reply (and ignores the others), to measure a client's own
 *    cost against a peer that costs next to nothing.
 *
 * Pinning uses pthread_setaffinity_np (Linux, _GNU_SOURCE). Elsewhere rc_pin_supported()
 * returns 0 and a CPU argument other than -1 makes the call fail, so callers degrade to
 * unpinned runs. On platforms without POSIX sockets and threads everything returns failure.
 * The sources stay C89 (checked by `make test-c` with -std=c89 -pedantic -Werror).
 */
#ifdef __linux__
#define _GNU_SOURCE
#else
#define _POSIX_C_SOURCE 200112L
#endif

#include <stdlib.h>
#include <string.h>

#include "robocli_core.h"
#include "netio.h"

#if defined(_WIN32) || !(defined(__unix__) || defined(__APPLE__))

int rc_pin_supported(void) { return 0; }

rc_pingpong *rc_pingpong_new(size_t msg_size, int echo_cpu)
{
    (void)msg_size;
    (void)echo_cpu;
    return NULL;
}

int rc_pingpong_run(rc_pingpong *p, size_t n, int cpu, double *out_rtt)
{
    (void)p;
    (void)n;
    (void)cpu;
    (void)out_rtt;
    return -1;
}

void rc_pingpong_free(rc_pingpong *p) { (void)p; }

rc_responder *rc_responder_new(const unsigned char *keys, const size_t *key_lens,
                               const unsigned char *replies, const size_t *reply_lens,
                               size_t n_entries)
{
    (void)keys;
    (void)key_lens;
    (void)replies;
    (void)reply_lens;
    (void)n_entries;
    return NULL;
}

int rc_responder_start(rc_responder *r, int cpu)
{
    (void)r;
    (void)cpu;
    return -1;
}

void rc_responder_get_stats(const rc_responder *r, rc_responder_stats *out)
{
    (void)r;
    memset(out, 0, sizeof(*out));
}

int rc_responder_stop(rc_responder *r)
{
    (void)r;
    return -1;
}

void rc_responder_free(rc_responder *r) { (void)r; }

#else

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <time.h>
#include <unistd.h>
#include <sys/types.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <arpa/inet.h>
#ifdef __linux__
#include <sched.h>
#endif

#define BN_POLL_MS 100       /* longest a responder wait lasts before it looks at `stop` */
#define BN_SEND_TIMEOUT_S 1  /* a peer that does not read is dropped after this */
#define BN_MAX_ENTRY 4096u   /* largest key or reply of a responder table entry */
#define BN_MAX_ENTRIES 256u

/* ------------------------------------------------------------------ helpers */

int rc_pin_supported(void)
{
#ifdef __linux__
    return 1;
#else
    return 0;
#endif
}

/* Pin the calling thread to `cpu` (-1: leave it). When `saved` is given, the previous mask
 * is stored there (Linux) so bn_unpin can restore it. 0 on success, -1 if impossible. */
#ifdef __linux__
typedef cpu_set_t bn_mask;
#else
typedef int bn_mask;
#endif

static int bn_pin(int cpu, bn_mask *saved)
{
#ifdef __linux__
    cpu_set_t set;
    if (cpu < 0) {
        return 0;
    }
    if (cpu >= CPU_SETSIZE) {
        return -1;
    }
    if (saved != NULL && pthread_getaffinity_np(pthread_self(), sizeof(*saved), saved) != 0) {
        return -1;
    }
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    return pthread_setaffinity_np(pthread_self(), sizeof(set), &set) == 0 ? 0 : -1;
#else
    (void)saved;
    return cpu < 0 ? 0 : -1;
#endif
}

static void bn_unpin(int cpu, const bn_mask *saved)
{
#ifdef __linux__
    if (cpu >= 0) {
        pthread_setaffinity_np(pthread_self(), sizeof(*saved), saved);
    }
#else
    (void)cpu;
    (void)saved;
#endif
}

/* A listening loopback socket on an ephemeral port; its port in *port. -1 on failure. */
static int bn_listen(int *port)
{
    struct sockaddr_in addr;
    socklen_t alen = sizeof(addr);
    int one = 1;
    int fd = socket(AF_INET, SOCK_STREAM, 0);

    if (fd < 0) {
        return -1;
    }
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, (const void *)&one, sizeof(one));
    memset(&addr, 0, sizeof(addr));
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    addr.sin_port = 0;
    if (bind(fd, (struct sockaddr *)&addr, sizeof(addr)) != 0 || listen(fd, 4) != 0 ||
        getsockname(fd, (struct sockaddr *)&addr, &alen) != 0) {
        close(fd);
        return -1;
    }
    *port = (int)ntohs(addr.sin_port);
    return fd;
}

/* ------------------------------------------------------------------ ping-pong */

struct rc_pingpong {
    int cfd;          /* the calling thread's end */
    int sfd;          /* the echo thread's end */
    size_t msg_size;
    int echo_cpu;
    int pin_failed;   /* set by the echo thread when it could not pin itself */
    unsigned char *buf;
    pthread_t th;
    int started;
};

static void *bn_echo_main(void *arg)
{
    rc_pingpong *p = (rc_pingpong *)arg;
    unsigned char *buf = (unsigned char *)malloc(p->msg_size);

    if (bn_pin(p->echo_cpu, NULL) != 0) {
        p->pin_failed = 1;
    }
    if (buf != NULL) {
        /* echo until the other end shuts down (rc_pingpong_free) or an error */
        while (rc_net_recv_all(p->sfd, buf, p->msg_size) == 0 &&
               rc_net_send_all(p->sfd, buf, p->msg_size) == 0) {
        }
        free(buf);
    }
    shutdown(p->sfd, SHUT_RDWR);
    return NULL;
}

rc_pingpong *rc_pingpong_new(size_t msg_size, int echo_cpu)
{
    rc_pingpong *p;
    int lfd;
    int port = 0;
    struct sockaddr_in addr;

    if (msg_size == 0 || msg_size > 65536u) {
        return NULL;
    }
#ifndef __linux__
    if (echo_cpu >= 0) {
        return NULL;
    }
#endif
    p = (rc_pingpong *)calloc(1, sizeof(*p));
    if (p == NULL) {
        return NULL;
    }
    p->cfd = -1;
    p->sfd = -1;
    p->msg_size = msg_size;
    p->echo_cpu = echo_cpu;
    p->buf = (unsigned char *)malloc(msg_size);
    lfd = bn_listen(&port);
    if (p->buf == NULL || lfd < 0) {
        goto fail;
    }
    memset(p->buf, 0x5A, msg_size);
    memset(&addr, 0, sizeof(addr));
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    addr.sin_port = htons((unsigned short)port);
    p->cfd = socket(AF_INET, SOCK_STREAM, 0);
    /* loopback connect completes against the backlog before accept */
    if (p->cfd < 0 || connect(p->cfd, (struct sockaddr *)&addr, sizeof(addr)) != 0) {
        goto fail;
    }
    p->sfd = accept(lfd, NULL, NULL);
    if (p->sfd < 0) {
        goto fail;
    }
    close(lfd);
    lfd = -1;
    rc_net_nodelay(p->cfd);
    rc_net_nodelay(p->sfd);
    if (pthread_create(&p->th, NULL, bn_echo_main, p) != 0) {
        goto fail;
    }
    p->started = 1;
    return p;

fail:
    if (lfd >= 0) {
        close(lfd);
    }
    rc_pingpong_free(p);
    return NULL;
}

int rc_pingpong_run(rc_pingpong *p, size_t n, int cpu, double *out_rtt)
{
    bn_mask saved;
    size_t i;

    if (p == NULL || !p->started || p->pin_failed) {
        return -1;
    }
    if (bn_pin(cpu, &saved) != 0) {
        return -2;
    }
    for (i = 0; i < n; i++) {
        double t0 = rc_net_now();
        if (rc_net_send_all(p->cfd, p->buf, p->msg_size) != 0 ||
            rc_net_recv_all(p->cfd, p->buf, p->msg_size) != 0) {
            break;
        }
        out_rtt[i] = rc_net_now() - t0;
    }
    bn_unpin(cpu, &saved);
    if (p->pin_failed) {
        return -2;
    }
    return i == n ? 0 : -1;
}

void rc_pingpong_free(rc_pingpong *p)
{
    if (p == NULL) {
        return;
    }
    if (p->cfd >= 0) {
        shutdown(p->cfd, SHUT_RDWR); /* the echo thread sees end of stream and returns */
    }
    if (p->started) {
        pthread_join(p->th, NULL);
    }
    if (p->sfd >= 0) {
        close(p->sfd);
    }
    if (p->cfd >= 0) {
        close(p->cfd);
    }
    free(p->buf);
    free(p);
}

/* ------------------------------------------------------------------ ARCOS responder */

struct rc_responder {
    size_t n;
    unsigned char **keys;
    size_t *key_lens;
    unsigned char **replies;
    size_t *reply_lens;
    int lfd;
    int wake[2];      /* a byte written to wake[1] ends the thread's waits at once */
    int cpu;
    volatile int stop;
    int started;
    pthread_t th;
    pthread_mutex_t mu;
    rc_responder_stats st;
};

rc_responder *rc_responder_new(const unsigned char *keys, const size_t *key_lens,
                               const unsigned char *replies, const size_t *reply_lens,
                               size_t n_entries)
{
    rc_responder *r;
    size_t i;
    size_t ko = 0;
    size_t ro = 0;

    if (n_entries > BN_MAX_ENTRIES) {
        return NULL;
    }
    for (i = 0; i < n_entries; i++) {
        if (key_lens[i] == 0 || key_lens[i] > BN_MAX_ENTRY || reply_lens[i] > BN_MAX_ENTRY) {
            return NULL;
        }
    }
    r = (rc_responder *)calloc(1, sizeof(*r));
    if (r == NULL) {
        return NULL;
    }
    r->lfd = -1;
    r->wake[0] = -1;
    r->wake[1] = -1;
    r->cpu = -1;
    if (pthread_mutex_init(&r->mu, NULL) != 0) {
        free(r);
        return NULL;
    }
    r->n = n_entries;
    /* calloc(0) may return NULL: allocate at least one slot */
    r->keys = (unsigned char **)calloc(n_entries + 1, sizeof(*r->keys));
    r->replies = (unsigned char **)calloc(n_entries + 1, sizeof(*r->replies));
    r->key_lens = (size_t *)calloc(n_entries + 1, sizeof(*r->key_lens));
    r->reply_lens = (size_t *)calloc(n_entries + 1, sizeof(*r->reply_lens));
    if (r->keys == NULL || r->replies == NULL || r->key_lens == NULL || r->reply_lens == NULL) {
        rc_responder_free(r);
        return NULL;
    }
    for (i = 0; i < n_entries; i++) {
        r->keys[i] = (unsigned char *)malloc(key_lens[i]);
        r->replies[i] = (unsigned char *)malloc(reply_lens[i] + 1);
        if (r->keys[i] == NULL || r->replies[i] == NULL) {
            rc_responder_free(r);
            return NULL;
        }
        memcpy(r->keys[i], keys + ko, key_lens[i]);
        memcpy(r->replies[i], replies + ro, reply_lens[i]);
        r->key_lens[i] = key_lens[i];
        r->reply_lens[i] = reply_lens[i];
        ko += key_lens[i];
        ro += reply_lens[i];
    }
    return r;
}

static void bn_count(rc_responder *r, unsigned long *field)
{
    pthread_mutex_lock(&r->mu);
    (*field)++;
    pthread_mutex_unlock(&r->mu);
}

/* Wait until fd is readable or the responder is told to stop. 1 readable, 0 stop, -1 error */
static int bn_wait(rc_responder *r, int fd)
{
    struct pollfd pf[2];

    while (!r->stop) {
        int k;
        pf[0].fd = fd;
        pf[0].events = POLLIN;
        pf[0].revents = 0;
        pf[1].fd = r->wake[0];
        pf[1].events = POLLIN;
        pf[1].revents = 0;
        k = poll(pf, 2, BN_POLL_MS);
        if (k < 0) {
            if (errno == EINTR) {
                continue;
            }
            return -1;
        }
        if (pf[1].revents != 0) {
            return 0;
        }
        if (pf[0].revents != 0) {
            return 1;
        }
    }
    return 0;
}

/* Answer one connection's frames until it closes, fails, or the responder stops. */
static void bn_serve(rc_responder *r, int fd)
{
    unsigned char chunk[4096];
    rc_framer *f = rc_framer_new(RC_PROTO_ARCOS, 0);
    struct timeval tv;

    if (f == NULL) {
        return;
    }
    tv.tv_sec = BN_SEND_TIMEOUT_S;
    tv.tv_usec = 0;
    setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, (const void *)&tv, sizeof(tv));
    rc_net_nodelay(fd);
    while (bn_wait(r, fd) == 1) {
        const unsigned char *frame;
        size_t len;
        ssize_t k = recv(fd, chunk, sizeof(chunk), 0);
        if (k < 0 && errno == EINTR) {
            continue;
        }
        if (k <= 0 || rc_framer_feed(f, chunk, (size_t)k) != 0) {
            break;
        }
        while (rc_framer_next(f, &frame, &len)) {
            /* payload: type byte + data, between FA FB N and the checksum */
            const unsigned char *payload = frame + 3;
            size_t plen = len - 5;
            size_t i;
            bn_count(r, &r->st.frames);
            for (i = 0; i < r->n; i++) {
                if (r->key_lens[i] == plen && memcmp(r->keys[i], payload, plen) == 0) {
                    break;
                }
            }
            if (i == r->n) {
                continue;
            }
            /* counted first, so a peer that has read the reply always sees it counted */
            bn_count(r, &r->st.replies);
            if (r->reply_lens[i] > 0 && rc_net_send_all(fd, r->replies[i], r->reply_lens[i]) != 0) {
                goto done;
            }
        }
    }
done:
    rc_framer_free(f);
}

static void *bn_responder_main(void *arg)
{
    rc_responder *r = (rc_responder *)arg;

    if (bn_pin(r->cpu, NULL) != 0) {
        pthread_mutex_lock(&r->mu);
        r->st.pin_failed = 1;
        pthread_mutex_unlock(&r->mu);
    }
    while (bn_wait(r, r->lfd) == 1) {
        int fd = accept(r->lfd, NULL, NULL);
        if (fd < 0) {
            if (errno == EINTR || errno == EAGAIN || errno == ECONNABORTED) {
                continue;
            }
            break;
        }
        bn_count(r, &r->st.connections);
        bn_serve(r, fd); /* one client at a time: the next waits in the backlog */
        close(fd);
    }
    return NULL;
}

int rc_responder_start(rc_responder *r, int cpu)
{
    int port = 0;
    int i;

    if (r == NULL || r->started) {
        return -1;
    }
#ifndef __linux__
    if (cpu >= 0) {
        return -1;
    }
#endif
    if (pipe(r->wake) != 0) {
        r->wake[0] = r->wake[1] = -1;
        return -1;
    }
    for (i = 0; i < 2; i++) {
        fcntl(r->wake[i], F_SETFD, FD_CLOEXEC);
    }
    r->lfd = bn_listen(&port);
    if (r->lfd < 0) {
        return -1;
    }
    fcntl(r->lfd, F_SETFD, FD_CLOEXEC);
    r->cpu = cpu;
    r->stop = 0;
    if (pthread_create(&r->th, NULL, bn_responder_main, r) != 0) {
        return -1;
    }
    r->started = 1;
    return port;
}

void rc_responder_get_stats(const rc_responder *r, rc_responder_stats *out)
{
    pthread_mutex_lock((pthread_mutex_t *)&r->mu);
    *out = r->st;
    pthread_mutex_unlock((pthread_mutex_t *)&r->mu);
}

int rc_responder_stop(rc_responder *r)
{
    unsigned char one = 1;
    ssize_t k;

    if (r == NULL || !r->started) {
        return -1;
    }
    r->stop = 1;
    do {
        k = write(r->wake[1], &one, 1);
    } while (k < 0 && errno == EINTR);
    /* the thread looks at `stop` at least every BN_POLL_MS; a blocked send gives up after
     * BN_SEND_TIMEOUT_S: the join is bounded */
    pthread_join(r->th, NULL);
    r->started = 0;
    return 0;
}

void rc_responder_free(rc_responder *r)
{
    size_t i;

    if (r == NULL) {
        return;
    }
    if (r->started) {
        rc_responder_stop(r);
    }
    if (r->lfd >= 0) {
        close(r->lfd);
    }
    for (i = 0; i < 2; i++) {
        if (r->wake[i] >= 0) {
            close(r->wake[i]);
        }
    }
    if (r->keys != NULL) {
        for (i = 0; i < r->n; i++) {
            free(r->keys[i]);
        }
    }
    if (r->replies != NULL) {
        for (i = 0; i < r->n; i++) {
            free(r->replies[i]);
        }
    }
    free(r->keys);
    free(r->replies);
    free(r->key_lens);
    free(r->reply_lens);
    pthread_mutex_destroy(&r->mu);
    free(r);
}

#endif
