/*
 * Stream framers for ARCOS, Simple Message (LE/BE), ros4mat and SCIP 2.0 (rules in scip.c).
 *
 * The framer owns one growable buffer [start, end). Frames are returned as pointers
 * into it; bytes are only moved (compacted) inside rc_framer_feed, so a frame stays
 * valid until the next feed/next/reset. Compaction happens only when the dead space
 * in front is at least as large as the live data, so feeding is amortised O(n).
 * Garbage is skipped one byte at a time.
 */
#include <stdlib.h>
#include <string.h>

#include "robocli_core.h"

#define RC_ARCOS_DEFAULT_MAX 258u
#define RC_SM_DEFAULT_MAX 4100u
#define RC_R4M_HEADER 27u
#define RC_R4M_DEFAULT_MAX (27u + 16u * 1024u * 1024u)
#define RC_SCIP_DEFAULT_MAX 65536u
#define RC_SCIP_MAX_ECHO 64u
#define RC_SCIP_MAX_LINE 128u
#define RC_INITIAL_CAP 4096u

struct rc_framer {
    int proto;
    size_t max_frame;
    unsigned char *buf;
    size_t cap;
    size_t start;
    size_t end;
    rc_framer_stats st;
};

/* Per protocol (RC_PROTO_ARCOS..RC_PROTO_SCIP2): the smallest frame, the default max_frame. */
static const size_t MIN_FRAME[] = {0, 6, 16, 16, RC_R4M_HEADER, 8};
static const size_t DEFAULT_MAX[] = {0, RC_ARCOS_DEFAULT_MAX, RC_SM_DEFAULT_MAX, RC_SM_DEFAULT_MAX,
                                     RC_R4M_DEFAULT_MAX, RC_SCIP_DEFAULT_MAX};

rc_framer *rc_framer_new(int proto, size_t max_frame)
{
    rc_framer *f;

    if (proto < RC_PROTO_ARCOS || proto > RC_PROTO_SCIP2) {
        return NULL;
    }
    if (max_frame == 0) {
        max_frame = DEFAULT_MAX[proto];
    }
    if (max_frame < MIN_FRAME[proto]) {
        return NULL;
    }
    f = (rc_framer *)malloc(sizeof(*f));
    if (f == NULL) {
        return NULL;
    }
    f->proto = proto;
    f->max_frame = max_frame;
    f->cap = RC_INITIAL_CAP;
    f->buf = (unsigned char *)malloc(f->cap);
    if (f->buf == NULL) {
        free(f);
        return NULL;
    }
    f->start = 0;
    f->end = 0;
    memset(&f->st, 0, sizeof(f->st));
    return f;
}

void rc_framer_free(rc_framer *f)
{
    if (f != NULL) {
        free(f->buf);
        free(f);
    }
}

void rc_framer_reset(rc_framer *f)
{
    f->start = 0;
    f->end = 0;
}

int rc_framer_feed(rc_framer *f, const unsigned char *data, size_t n)
{
    size_t live;

    if (n == 0) {
        return 0;
    }
    if (f->start == f->end) {
        f->start = 0;
        f->end = 0;
    }
    if (n > f->cap - f->end) {
        live = f->end - f->start;
        if (n > (size_t)-1 - live) {
            return -1;
        }
        if (live + n <= f->cap && f->start >= live) {
            /* enough dead space in front: compact (cost <= bytes already consumed) */
            memmove(f->buf, f->buf + f->start, live);
        } else {
            size_t newcap = f->cap;
            unsigned char *nb;
            while (newcap < live + n) {
                if (newcap > ((size_t)-1) / 2) {
                    newcap = live + n;
                    break;
                }
                newcap *= 2;
            }
            if (newcap < 2 * live && newcap <= ((size_t)-1) / 2) {
                newcap *= 2;
            }
            nb = (unsigned char *)malloc(newcap);
            if (nb == NULL) {
                return -1;
            }
            memcpy(nb, f->buf + f->start, live);
            free(f->buf);
            f->buf = nb;
            f->cap = newcap;
        }
        f->start = 0;
        f->end = live;
    }
    memcpy(f->buf + f->end, data, n);
    f->end += n;
    return 0;
}

static unsigned long rd_le32(const unsigned char *p)
{
    return (unsigned long)p[0] | ((unsigned long)p[1] << 8) | ((unsigned long)p[2] << 16) |
           ((unsigned long)p[3] << 24);
}

static unsigned long rd_be32(const unsigned char *p)
{
    return (unsigned long)p[3] | ((unsigned long)p[2] << 8) | ((unsigned long)p[1] << 16) |
           ((unsigned long)p[0] << 24);
}

/* The three binary framers share one scan (next_binary); each protocol only says what the
 * bytes at the scan position are (a check_fn): */
#define FR_WAIT 0    /* a frame may start here: wait for more bytes */
#define FR_FRAME 1   /* a whole frame of *n bytes */
#define FR_DROP 2    /* *n bytes that cannot start a frame */
#define FR_BAD_LEN 3 /* an implausible length: drop one byte, counted */
#define FR_BAD_SUM 4 /* a wrong checksum: drop one byte, counted */

typedef int (*check_fn)(const rc_framer *f, const unsigned char *b, size_t avail, size_t *n);

static int next_binary(rc_framer *f, check_fn check, const unsigned char **frame, size_t *len)
{
    size_t p = f->start;

    for (;;) {
        size_t n = 0;

        switch (check(f, f->buf + p, f->end - p, &n)) {
        case FR_WAIT:
            f->start = p;
            return 0;
        case FR_DROP:
            f->st.dropped_bytes += (unsigned long)n;
            p += n;
            break;
        case FR_BAD_LEN:
            f->st.bad_lengths++;
            f->st.dropped_bytes++;
            p++;
            break;
        case FR_BAD_SUM:
            f->st.bad_checksums++;
            f->st.dropped_bytes++;
            p++;
            break;
        default:
            *frame = f->buf + p;
            *len = n;
            f->start = p + n;
            f->st.frames++;
            return 1;
        }
    }
}

static int check_arcos(const rc_framer *f, const unsigned char *b, size_t avail, size_t *n)
{
    size_t count;
    size_t total;

    if (avail == 0) {
        return FR_WAIT;
    }
    if (b[0] != 0xFA) {
        const unsigned char *q = (const unsigned char *)memchr(b, 0xFA, avail);
        *n = q == NULL ? avail : (size_t)(q - b);
        return FR_DROP;
    }
    if (avail < 2) {
        return FR_WAIT;
    }
    if (b[1] != 0xFB) {
        *n = 1;
        return FR_DROP;
    }
    if (avail < 3) {
        return FR_WAIT;
    }
    count = b[2];
    total = count + 3;
    if (count < 3 || total > f->max_frame) {
        return FR_BAD_LEN;
    }
    if (avail < total) {
        return FR_WAIT;
    }
    if (rc_arcos_checksum(b + 3, count - 2) !=
        (((unsigned int)b[total - 2] << 8) | (unsigned int)b[total - 1])) {
        return FR_BAD_SUM;
    }
    *n = total;
    return FR_FRAME;
}

/* A length-prefixed frame of `total` bytes (0: an implausible header) with `avail` here. */
static int check_total(size_t total, size_t avail, size_t *n)
{
    if (total == 0) {
        return FR_BAD_LEN;
    }
    if (avail < total) {
        return FR_WAIT;
    }
    *n = total;
    return FR_FRAME;
}

static int check_sm(const rc_framer *f, const unsigned char *b, size_t avail, size_t *n)
{
    unsigned long length;
    unsigned long maxlen = (unsigned long)(f->max_frame - 4);

    if (avail < 4) {
        return FR_WAIT;
    }
    length = f->proto == RC_PROTO_SM_BE ? rd_be32(b) : rd_le32(b);
    return check_total(length < 12 || length > maxlen ? 0 : (size_t)length + 4, avail, n);
}

/* A ros4mat message id: 0x0X commands, 0x1X acks, 0x2X sensor data, 0x8X/0x9X reserved
 * "to sensor". Checking the id class (not its meaning) lets the framer resynchronise:
 * without it, garbage right before a header reads as a plausible error packet. */
static int r4m_plausible_id(unsigned char type)
{
    unsigned char cls = (unsigned char)(type >> 4);
    return type != 0 && (cls <= 2 || cls == 8 || cls == 9);
}

/* Body length of a ros4mat header, or -1 when the header is not plausible. */
static int r4m_body(const unsigned char *h, size_t max_frame, size_t *body)
{
    int error = h[1] != 0;
    unsigned long size = rd_le32(h + 6);
    unsigned long usize = rd_le32(h + 10);
    unsigned long csize = rd_le32(h + 14);
    unsigned char ctype = h[18];
    unsigned long b;

    if (ctype > 1 || h[1] > 1 || !r4m_plausible_id(h[0])) {
        return -1;
    }
    if (ctype == 0 && !error && size != 0 && csize != usize) {
        return -1;
    }
    if (error) {
        b = csize;
    } else if (size == 0) {
        b = 0;
    } else {
        b = csize;
    }
    if (b > (unsigned long)(max_frame - RC_R4M_HEADER)) {
        return -1;
    }
    *body = (size_t)b;
    return 0;
}

static int check_r4m(const rc_framer *f, const unsigned char *b, size_t avail, size_t *n)
{
    size_t body;

    if (avail < RC_R4M_HEADER) {
        return FR_WAIT;
    }
    if (r4m_body(b, f->max_frame, &body) != 0) {
        return FR_BAD_LEN;
    }
    return check_total(RC_R4M_HEADER + body, avail, n);
}

/* SCIP line at `at` in buf[0..n): SL_OK (*cend = content end, CR dropped; *nxt = after the
 * LF), SL_GARBAGE (*nxt = after the bad byte), SL_LONG (more than `limit` chars; *nxt = the
 * bytes scanned, or after the LF), SL_WAIT (its end has not arrived yet). */
#define SL_OK 0
#define SL_GARBAGE 1
#define SL_LONG 2
#define SL_WAIT 3

static int scip_line(const unsigned char *buf, size_t n, size_t at, size_t limit, size_t *cend,
                     size_t *nxt)
{
    size_t i = at;

    for (;;) {
        unsigned char c;
        if (i >= n) {
            if (i - at > limit) {
                *nxt = i;
                return SL_LONG;
            }
            return SL_WAIT;
        }
        c = buf[i];
        if (c == '\n') {
            size_t e = (i > at && buf[i - 1] == '\r') ? i - 1 : i;
            *nxt = i + 1;
            if (e - at > limit) {
                return SL_LONG;
            }
            *cend = e;
            return SL_OK;
        }
        if (c < 0x20 || c > 0x7E) {
            if (c != '\r') {
                *nxt = i + 1;
                return SL_GARBAGE;
            }
            if (i + 1 >= n) {
                return SL_WAIT;
            }
            if (buf[i + 1] != '\n') {
                *nxt = i + 1;
                return SL_GARBAGE;
            }
        }
        if (i - at > limit) {
            *nxt = i;
            return SL_LONG;
        }
        i++;
    }
}

static void scip_drop(rc_framer *f, size_t *p, size_t k)
{
    *p += k;
    f->st.dropped_bytes += k;
}

static int next_scip(rc_framer *f, const unsigned char **frame, size_t *len)
{
    size_t p = f->start;

    while (p < f->end) {
        const unsigned char *b = f->buf + p;
        size_t n = f->end - p;
        size_t cend = 0, nxt = 0, send = 0, snxt = 0, at, lend = 0, lnxt = 0;
        int r;

        if (b[0] == '\n') {
            scip_drop(f, &p, 1);
            continue;
        }
        r = scip_line(b, n, 0, RC_SCIP_MAX_ECHO, &cend, &nxt);
        if (r == SL_GARBAGE) {
            f->st.bad_lengths++;
            scip_drop(f, &p, nxt);
            continue;
        }
        if (r == SL_LONG || (r == SL_OK && cend == 0)) {
            scip_drop(f, &p, nxt);
            continue;
        }
        if (r == SL_OK) {
            r = scip_line(b, n, nxt, 4, &send, &snxt);
        }
        if (r == SL_OK && send - nxt == 3 &&
            b[nxt + 2] != (unsigned char)rc_scip_checksum(b + nxt, 2)) {
            f->st.bad_checksums++;
            scip_drop(f, &p, nxt);
            continue;
        }
        if (r == SL_GARBAGE || r == SL_LONG || (r == SL_OK && send - nxt != 1 && send - nxt != 3)) {
            scip_drop(f, &p, nxt);
            continue;
        }
        if (r == SL_OK) {
            at = snxt;
            for (;;) {
                if (at > f->max_frame) {
                    r = SL_LONG;
                    break;
                }
                r = scip_line(b, n, at, RC_SCIP_MAX_LINE, &lend, &lnxt);
                if (r != SL_OK) {
                    break;
                }
                if (lend == at) {
                    if (lnxt > f->max_frame) {
                        r = SL_LONG;
                        break;
                    }
                    *frame = b;
                    *len = lnxt;
                    f->start = p + lnxt;
                    f->st.frames++;
                    return 1;
                }
                at = lnxt;
            }
            if (r != SL_WAIT) {
                f->st.bad_lengths++;
                scip_drop(f, &p, nxt);
                continue;
            }
        }
        /* waiting for more bytes: unless the candidate has outgrown max_frame */
        if (n > f->max_frame) {
            const unsigned char *lf = (const unsigned char *)memchr(b, '\n', n);
            f->st.bad_lengths++;
            scip_drop(f, &p, lf != NULL ? (size_t)(lf - b) + 1 : n);
            continue;
        }
        break;
    }
    f->start = p;
    return 0;
}

int rc_framer_next(rc_framer *f, const unsigned char **frame, size_t *len)
{
    switch (f->proto) {
    case RC_PROTO_SCIP2:
        return next_scip(f, frame, len);
    case RC_PROTO_ARCOS:
        return next_binary(f, check_arcos, frame, len);
    case RC_PROTO_SM_LE:
    case RC_PROTO_SM_BE:
        return next_binary(f, check_sm, frame, len);
    default:
        return next_binary(f, check_r4m, frame, len);
    }
}

void rc_framer_get_stats(const rc_framer *f, rc_framer_stats *out)
{
    *out = f->st;
}

size_t rc_framer_pending(const rc_framer *f)
{
    return f->end - f->start;
}

unsigned long rc_framer_count(rc_framer *f, const unsigned char *data, size_t n, size_t chunk)
{
    unsigned long count = 0;
    size_t off = 0;
    const unsigned char *fr;
    size_t len;

    if (chunk == 0) {
        chunk = n;
    }
    while (off < n) {
        size_t k = n - off < chunk ? n - off : chunk;
        if (rc_framer_feed(f, data + off, k) != 0) {
            break;
        }
        off += k;
        while (rc_framer_next(f, &fr, &len)) {
            count++;
        }
    }
    return count;
}
