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

rc_framer *rc_framer_new(int proto, size_t max_frame)
{
    rc_framer *f;
    size_t min_frame;

    switch (proto) {
    case RC_PROTO_ARCOS:
        min_frame = 6;
        if (max_frame == 0) {
            max_frame = RC_ARCOS_DEFAULT_MAX;
        }
        break;
    case RC_PROTO_SM_LE:
    case RC_PROTO_SM_BE:
        min_frame = 16;
        if (max_frame == 0) {
            max_frame = RC_SM_DEFAULT_MAX;
        }
        break;
    case RC_PROTO_ROS4MAT:
        min_frame = RC_R4M_HEADER;
        if (max_frame == 0) {
            max_frame = RC_R4M_DEFAULT_MAX;
        }
        break;
    case RC_PROTO_SCIP2:
        min_frame = 8;
        if (max_frame == 0) {
            max_frame = RC_SCIP_DEFAULT_MAX;
        }
        break;
    default:
        return NULL;
    }
    if (max_frame < min_frame) {
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

static int next_arcos(rc_framer *f, const unsigned char **frame, size_t *len)
{
    unsigned char *buf = f->buf;
    size_t p = f->start;
    size_t end = f->end;

    for (;;) {
        size_t count;
        size_t total;
        unsigned int ck;

        if (p >= end) {
            f->start = p;
            return 0;
        }
        if (buf[p] != 0xFA) {
            const unsigned char *q = (const unsigned char *)memchr(buf + p, 0xFA, end - p);
            size_t np = q == NULL ? end : (size_t)(q - buf);
            f->st.dropped_bytes += (unsigned long)(np - p);
            p = np;
            continue;
        }
        if (end - p < 2) {
            f->start = p;
            return 0;
        }
        if (buf[p + 1] != 0xFB) {
            f->st.dropped_bytes++;
            p++;
            continue;
        }
        if (end - p < 3) {
            f->start = p;
            return 0;
        }
        count = buf[p + 2];
        total = count + 3;
        if (count < 3 || total > f->max_frame) {
            f->st.bad_lengths++;
            f->st.dropped_bytes++;
            p++;
            continue;
        }
        if (end - p < total) {
            f->start = p;
            return 0;
        }
        ck = rc_arcos_checksum(buf + p + 3, count - 2);
        if (ck != (((unsigned int)buf[p + total - 2] << 8) | (unsigned int)buf[p + total - 1])) {
            f->st.bad_checksums++;
            f->st.dropped_bytes++;
            p++;
            continue;
        }
        *frame = buf + p;
        *len = total;
        f->start = p + total;
        f->st.frames++;
        return 1;
    }
}

static int next_sm(rc_framer *f, const unsigned char **frame, size_t *len)
{
    unsigned char *buf = f->buf;
    size_t p = f->start;
    size_t end = f->end;
    int be = f->proto == RC_PROTO_SM_BE;
    unsigned long maxlen = (unsigned long)(f->max_frame - 4);

    for (;;) {
        unsigned long length;
        size_t total;

        if (end - p < 4) {
            f->start = p;
            return 0;
        }
        length = be ? rd_be32(buf + p) : rd_le32(buf + p);
        if (length < 12 || length > maxlen) {
            f->st.bad_lengths++;
            f->st.dropped_bytes++;
            p++;
            continue;
        }
        total = (size_t)length + 4;
        if (end - p < total) {
            f->start = p;
            return 0;
        }
        *frame = buf + p;
        *len = total;
        f->start = p + total;
        f->st.frames++;
        return 1;
    }
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

static int next_r4m(rc_framer *f, const unsigned char **frame, size_t *len)
{
    unsigned char *buf = f->buf;
    size_t p = f->start;
    size_t end = f->end;

    for (;;) {
        size_t body;
        size_t total;

        if (end - p < RC_R4M_HEADER) {
            f->start = p;
            return 0;
        }
        if (r4m_body(buf + p, f->max_frame, &body) != 0) {
            f->st.bad_lengths++;
            f->st.dropped_bytes++;
            p++;
            continue;
        }
        total = RC_R4M_HEADER + body;
        if (end - p < total) {
            f->start = p;
            return 0;
        }
        *frame = buf + p;
        *len = total;
        f->start = p + total;
        f->st.frames++;
        return 1;
    }
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
        return next_arcos(f, frame, len);
    case RC_PROTO_SM_LE:
    case RC_PROTO_SM_BE:
        return next_sm(f, frame, len);
    default:
        return next_r4m(f, frame, len);
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
