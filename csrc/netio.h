/*
 * Internal to the C core (not part of robocli_core.h, not exported through cffi's cdef):
 * whole-buffer send/receive on a blocking socket, a monotonic clock and TCP_NODELAY, shared
 * by the ping-pong floor (pingpong.c, which defines them) and the benchmark peers
 * (benchnet.c). POSIX only.
 */
#ifndef ROBOCLI_NETIO_H
#define ROBOCLI_NETIO_H

#include <stddef.h>

/* Send all of p[0..len); retries on EINTR, never raises SIGPIPE. 0 on success, -1 on error. */
int rc_net_send_all(int fd, const unsigned char *p, size_t len);

/* Receive exactly len bytes into p; -1 on error or if the peer closed first. */
int rc_net_recv_all(int fd, unsigned char *p, size_t len);

/* Seconds on the monotonic clock. */
double rc_net_now(void);

/* Turn Nagle's algorithm off on a TCP socket (best effort: a failure is ignored). */
void rc_net_nodelay(int fd);

#endif
