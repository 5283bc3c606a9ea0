/*
 * Loopback TCP ping-pong: the machine's floor for request/acknowledge round trips.
 * POSIX threads + BSD sockets; other platforms get a stub returning -1.
 */
#define _POSIX_C_SOURCE 200112L

#include "robocli_core.h"
#include "netio.h"

#if defined(_WIN32) || !(defined(__unix__) || defined(__APPLE__))

int rc_pingpong_tcp(size_t n, size_t msg_size, double *out_rtt)
{
    (void)n;
    (void)msg_size;
    (void)out_rtt;
    return -1;
}

#else

#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include <sys/types.h>
#include <sys/socket.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <arpa/inet.h>

#ifdef MSG_NOSIGNAL
#define RC_SEND_FLAGS MSG_NOSIGNAL
#else
#define RC_SEND_FLAGS 0
#endif

typedef struct echo_args {
    int fd;
    size_t n;
    size_t msg_size;
    int rc;
} echo_args;

int rc_net_send_all(int fd, const unsigned char *p, size_t len)
{
    while (len > 0) {
        ssize_t k = send(fd, p, len, RC_SEND_FLAGS);
        if (k < 0) {
            if (errno == EINTR) {
                continue;
            }
            return -1;
        }
        p += k;
        len -= (size_t)k;
    }
    return 0;
}

int rc_net_recv_all(int fd, unsigned char *p, size_t len)
{
    while (len > 0) {
        ssize_t k = recv(fd, p, len, 0);
        if (k < 0) {
            if (errno == EINTR) {
                continue;
            }
            return -1;
        }
        if (k == 0) {
            return -1;
        }
        p += k;
        len -= (size_t)k;
    }
    return 0;
}

static void *echo_main(void *arg)
{
    echo_args *a = (echo_args *)arg;
    unsigned char *buf = (unsigned char *)malloc(a->msg_size);
    size_t i;

    a->rc = -1;
    if (buf == NULL) {
        shutdown(a->fd, SHUT_RDWR);
        return NULL;
    }
    for (i = 0; i < a->n; i++) {
        if (rc_net_recv_all(a->fd, buf, a->msg_size) != 0 ||
            rc_net_send_all(a->fd, buf, a->msg_size) != 0) {
            break;
        }
    }
    if (i == a->n) {
        a->rc = 0;
    } else {
        shutdown(a->fd, SHUT_RDWR);
    }
    free(buf);
    return NULL;
}

double rc_net_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

void rc_net_nodelay(int fd)
{
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, (const void *)&one, sizeof(one));
}

int rc_pingpong_tcp(size_t n, size_t msg_size, double *out_rtt)
{
    int lfd = -1;
    int cfd = -1;
    int sfd = -1;
    int rc = -1;
    int started = 0;
    struct sockaddr_in addr;
    socklen_t alen = sizeof(addr);
    unsigned char *buf = NULL;
    pthread_t th;
    echo_args args;
    size_t i;

    if (msg_size == 0) {
        msg_size = 1;
    }
    buf = (unsigned char *)malloc(msg_size);
    if (buf == NULL) {
        return -1;
    }
    memset(buf, 0x5A, msg_size);
    memset(&addr, 0, sizeof(addr));
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    addr.sin_port = 0;

    lfd = socket(AF_INET, SOCK_STREAM, 0);
    if (lfd < 0) {
        goto done;
    }
    if (bind(lfd, (struct sockaddr *)&addr, sizeof(addr)) != 0 || listen(lfd, 1) != 0 ||
        getsockname(lfd, (struct sockaddr *)&addr, &alen) != 0) {
        goto done;
    }
    cfd = socket(AF_INET, SOCK_STREAM, 0);
    if (cfd < 0) {
        goto done;
    }
    /* loopback connect completes against the backlog before accept */
    if (connect(cfd, (struct sockaddr *)&addr, sizeof(addr)) != 0) {
        goto done;
    }
    sfd = accept(lfd, NULL, NULL);
    if (sfd < 0) {
        goto done;
    }
    rc_net_nodelay(cfd);
    rc_net_nodelay(sfd);

    args.fd = sfd;
    args.n = n;
    args.msg_size = msg_size;
    args.rc = -1;
    if (pthread_create(&th, NULL, echo_main, &args) != 0) {
        goto done;
    }
    started = 1;

    for (i = 0; i < n; i++) {
        double t0 = rc_net_now();
        if (rc_net_send_all(cfd, buf, msg_size) != 0 ||
            rc_net_recv_all(cfd, buf, msg_size) != 0) {
            break;
        }
        out_rtt[i] = rc_net_now() - t0;
    }
    if (i == n) {
        rc = 0;
    } else {
        shutdown(cfd, SHUT_RDWR);
        shutdown(sfd, SHUT_RDWR);
    }

done:
    if (started) {
        pthread_join(th, NULL);
        if (args.rc != 0) {
            rc = -1;
        }
    }
    if (sfd >= 0) {
        close(sfd);
    }
    if (cfd >= 0) {
        close(cfd);
    }
    if (lfd >= 0) {
        close(lfd);
    }
    free(buf);
    return rc;
}

#endif
