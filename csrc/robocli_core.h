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
#define RC_PROTO_SCIP2    5 /* Hokuyo SCIP 2.0 reply: echo, status, lines, empty line */

typedef struct rc_framer rc_framer;

typedef struct rc_framer_stats {
    unsigned long frames;         /* complete, valid frames delivered              */
    unsigned long dropped_bytes;  /* bytes discarded while resynchronising         */
    unsigned long bad_checksums;  /* ARCOS frames whose checksum did not match      */
    unsigned long bad_lengths;    /* length/count fields outside the allowed range */
} rc_framer_stats;

/* max_frame: largest accepted frame, prefix/header included; 0 = protocol default
 * (ARCOS 258, Simple Message 4100 (= length 4096 + 4), ros4mat 27 + 16 MiB, SCIP 65536).
 * SCIP 2.0 resynchronises line by line, not byte by byte (scip.c has the rules).
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

/* ------------------------------------------------------------------ SCIP 2.0 */

/* Decode results of rc_scip_decode (0 = ok). */
#define RC_SCIP_OK        0
#define RC_SCIP_EGARBAGE  1 /* a byte that is not printable ASCII in a data line       */
#define RC_SCIP_ELINE     2 /* a data line of the wrong length or without LF: truncated */
#define RC_SCIP_ECHECKSUM 3 /* a data line whose sum char does not match              */
#define RC_SCIP_ECOUNT    4 /* data chars != count * width: truncated or too long      */
#define RC_SCIP_ECHAR     5 /* an encoded char outside '0'..'o'                         */

/* SCIP sum of n bytes: (sum & 0x3F) + 0x30. */
unsigned int rc_scip_checksum(const unsigned char *data, size_t n);

/* Decode the data lines of a scan reply (the bytes after the timestamp line, up to and
 * excluding the final empty line): each line holds 1..64 chars (exactly 64 but the last),
 * its sum char, an optional CR and LF. The stream must hold exactly `count` values of
 * `width` (2, 3 or 4) chars, which may straddle lines; they are written to out[0..count).
 * check = 0 skips the sums. Checks run per line in order (garbage, length, sum), then the
 * char count, then the chars. On error returns RC_SCIP_E* and sets *err_at to the offset
 * of the line (or char) at fault. */
int rc_scip_decode(const unsigned char *data, size_t n, int width, int check,
                   unsigned int *out, size_t count, size_t *err_at);

/* ------------------------------------------------------------------ ring buffer */

/* One writer, many readers. One ring of `capacity` fixed-size records, each with a
 * double timestamp. Each reader has its own cursor and its own limit (<= capacity):
 * when more than `limit` records are unread, the oldest are dropped for that reader
 * only and counted in its lost counter. Memory: one ring + O(readers).
 * Thread-safe (POSIX threads, Windows): each call takes the ring's own mutex for its C
 * work only, so one thread may push while many read, with no lock in the caller.
 * A reader id is only reused after remove_reader; a caller must not read an id it
 * removed. */
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


/* ------------------------------------------------------------------ benchmark peers */

/* 1 when threads can be pinned to a CPU (Linux), else 0: then every `cpu` argument below
 * must be -1 (unpinned) or the call fails. */
int rc_pin_supported(void);

/* A persistent loopback TCP ping-pong (TCP_NODELAY): an echo thread, pinned to `echo_cpu`
 * (-1: not pinned), and the thread that calls rc_pingpong_run. Runs can be short chunks, so
 * a caller stays interruptible. NULL on failure (sockets, threads, msg_size 0 or > 64 KiB). */
typedef struct rc_pingpong rc_pingpong;

rc_pingpong *rc_pingpong_new(size_t msg_size, int echo_cpu);
/* n round trips from the calling thread, pinned to `cpu` for the call (-1: as it is; the
 * previous affinity is restored). Each round trip in seconds goes to out_rtt.
 * 0 ok, -1 socket error, -2 a thread could not be pinned. */
int rc_pingpong_run(rc_pingpong *p, size_t n, int cpu, double *out_rtt);
void rc_pingpong_free(rc_pingpong *p); /* ends the echo thread (bounded) and closes */

/* A minimal ARCOS responder on 127.0.0.1 (ephemeral port), one client at a time, in its own
 * thread: for every complete ARCOS frame whose payload (type byte + data) equals a table
 * key, it writes that entry's reply bytes; other frames get no reply. The table is given as
 * n_entries keys (key_lens[i] bytes each, concatenated in `keys`) and replies (likewise);
 * it is copied. At most 256 entries of at most 4096 bytes. NULL on bad table or no memory. */
typedef struct rc_responder rc_responder;

typedef struct rc_responder_stats {
    unsigned long connections; /* clients accepted                          */
    unsigned long frames;      /* complete frames received                   */
    unsigned long replies;     /* replies written (counted as the write starts) */
    int pin_failed;            /* 1 when the thread could not be pinned      */
} rc_responder_stats;

rc_responder *rc_responder_new(const unsigned char *keys, const size_t *key_lens,
                               const unsigned char *replies, const size_t *reply_lens,
                               size_t n_entries);
/* Listen and start the thread, pinned to `cpu` (-1: not pinned). Returns the TCP port,
 * or -1 on failure. */
int rc_responder_start(rc_responder *r, int cpu);
void rc_responder_get_stats(const rc_responder *r, rc_responder_stats *out);
/* Stop the thread and join it: bounded (~0.1 s, ~1 s while a peer does not read).
 * 0 ok, -1 when it was not running. */
int rc_responder_stop(rc_responder *r);
void rc_responder_free(rc_responder *r); /* stops it first when running */

#endif /* ROBOCLI_CORE_H */
