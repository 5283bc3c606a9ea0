/*
 * robocli C core: the hot paths only (checksums, framers, multi-reader ring buffer,
 * timestamp alignment, loopback ping-pong floor). C89, no field meanings.
 *
 * Reached from Python only through robocli/core.py (cffi, API mode).
 * Counters are unsigned long (64-bit on LP64; differences are taken modulo 2^N so a
 * wrap of the 32-bit Windows type is harmless as long as fewer than 2^32 are pending).
 */
#ifndef ROBOCLI_CORE_H
#define ROBOCLI_CORE_H

#include <stddef.h>

/* ------------------------------------------------------------------ checksums */

/* ARCOS checksum over the type byte and data (bytes 3..N of a frame):
 * big-endian 16-bit pair sums, an odd last byte XORed in. Returns 0..65535. */
unsigned int rc_arcos_checksum(const unsigned char *data, size_t n);

/* ------------------------------------------------------------------ framers */

#define RC_PROTO_ARCOS    1 /* FA FB count type data.. cksum_hi cksum_lo          */
#define RC_PROTO_SM_LE    2 /* Simple Message, int32 length prefix little-endian  */
#define RC_PROTO_SM_BE    3 /* Simple Message, int32 length prefix big-endian     */
#define RC_PROTO_ROS4MAT  4 /* 27-byte header + body (error text / compressed)    */

typedef struct rc_framer rc_framer;

typedef struct rc_framer_stats {
    unsigned long frames;         /* complete, valid frames delivered              */
    unsigned long dropped_bytes;  /* bytes discarded while resynchronising         */
    unsigned long bad_checksums;  /* ARCOS frames whose checksum did not match      */
    unsigned long bad_lengths;    /* length/count fields outside the allowed range */
} rc_framer_stats;

/* max_frame: largest accepted frame, prefix/header included; 0 = protocol default
 * (ARCOS 258, Simple Message 4100 (= length 4096 + 4), ros4mat 27 + 16 MiB).
 * Returns NULL on bad protocol or out of memory. */
rc_framer *rc_framer_new(int proto, size_t max_frame);
void rc_framer_free(rc_framer *f);
void rc_framer_reset(rc_framer *f); /* forget buffered bytes; keep counters */

/* Append bytes of the stream (any chunking). 0 on success, -1 out of memory. */
int rc_framer_feed(rc_framer *f, const unsigned char *data, size_t n);

/* Next complete frame: returns 1 and sets *frame (points into the framer's buffer,
 * valid until the next feed/next/reset call) and *len (whole frame, sync/prefix
 * included); returns 0 when no complete frame is buffered. Garbage is skipped one
 * byte at a time, so a valid frame starting inside rejected bytes is still found. */
int rc_framer_next(rc_framer *f, const unsigned char **frame, size_t *len);

void rc_framer_get_stats(const rc_framer *f, rc_framer_stats *out);
size_t rc_framer_pending(const rc_framer *f); /* bytes buffered, not yet framed */

/* Benchmark helper: feed data in chunks of `chunk` bytes (0 = all at once), take
 * every frame out, return how many were found. */
unsigned long rc_framer_count(rc_framer *f, const unsigned char *data, size_t n, size_t chunk);

/* ------------------------------------------------------------------ ring buffer */

/* One writer, many readers. One ring of `capacity` fixed-size records, each with a
 * double timestamp. Each reader has its own cursor and its own limit (<= capacity):
 * when more than `limit` records are unread, the oldest are dropped for that reader
 * only and counted in its lost counter. Memory: one ring + O(readers).
 * Not thread-safe: the caller serialises push/read on one ring. */
typedef struct rc_ring rc_ring;

rc_ring *rc_ring_new(size_t record_size, size_t capacity);
void rc_ring_free(rc_ring *r);
size_t rc_ring_record_size(const rc_ring *r);
size_t rc_ring_capacity(const rc_ring *r);
unsigned long rc_ring_pushed(const rc_ring *r); /* records pushed since creation */

void rc_ring_push(rc_ring *r, double t, const void *record);
void rc_ring_push_many(rc_ring *r, const double *t, const void *records, size_t n);

/* New reader starting at the current head (sees only later records). limit 0 =
 * capacity; limit > capacity is clamped. Returns reader id >= 0, or -1. */
int rc_ring_add_reader(rc_ring *r, size_t limit);
void rc_ring_remove_reader(rc_ring *r, int reader);
size_t rc_ring_available(const rc_ring *r, int reader);
unsigned long rc_ring_lost(const rc_ring *r, int reader);

/* Copy up to max unread records of `reader`, oldest first, into t_out / rec_out
 * (rec_out holds max * record_size bytes); advance its cursor. Returns the count. */
size_t rc_ring_read(rc_ring *r, int reader, double *t_out, void *rec_out, size_t max);

/* ------------------------------------------------------------------ alignment */

/* ts: n sorted sample times of one stream; ref: m sorted reference times.
 * Nearest: out_idx[i] = index of the sample nearest ref[i] if |ts[j]-ref[i]| <= tol,
 * else -1 (ties go to the earlier sample). */
void rc_align_nearest(const double *ts, size_t n, const double *ref, size_t m, double tol,
                      long *out_idx);

/* Linear: out_idx[i] = j with ts[j] <= ref[i] <= ts[j+1] and out_w[i] the weight of
 * sample j+1 (value = (1-w)*x[j] + w*x[j+1]); a ref equal to the last sample gives
 * j = n-2, w = 1 (j = 0, w = 0 when n == 1 and ref == ts[0]); outside [ts[0], ts[n-1]]
 * gives -1 and w = 0. */
void rc_align_linear(const double *ts, size_t n, const double *ref, size_t m, long *out_idx,
                     double *out_w);

/* ------------------------------------------------------------------ latency floor */

/* The machine's floor for request/acknowledge round trips: two C threads ping-pong
 * `msg_size`-byte messages over a loopback TCP connection (TCP_NODELAY) `n` times.
 * Writes each round trip in seconds to out_rtt. Returns 0, or -1 on a socket error
 * (or on platforms without POSIX threads). */
int rc_pingpong_tcp(size_t n, size_t msg_size, double *out_rtt);

#endif /* ROBOCLI_CORE_H */
