/*
 * Internal to the C core (not part of robocli_core.h, not exported through cffi's cdef):
 * whole-buffer send/receive on a blocking socket, shared by the ping-pong floor
 * (pingpong.c) and the benchmark peers (benchnet.c). POSIX only.
 */
#ifndef ROBOCLI_NETIO_H
#define ROBOCLI_NETIO_H

#include <stddef.h>

/* Send all of p[0..len); retries on EINTR, never raises SIGPIPE. 0 on success, -1 on error. */
int rc_net_send_all(int fd, const unsigned char *p, size_t len);

/* Receive exactly len bytes into p; -1 on error or if the peer closed first. */
int rc_net_recv_all(int fd, unsigned char *p, size_t len);

#endif
