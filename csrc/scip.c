/*
 * Hokuyo SCIP 2.0: the checksum and the whole-scan decode of 2/3/4-char data lines.
 *
 * A scan's values are a stream of 6-bit chars (+ 0x30, most significant first) cut into
 * lines of 64 chars, each followed by its sum char and LF. Values straddle lines, so the
 * decode first walks the lines (checking each one) and then decodes the stream, skipping
 * every line's sum char and end. The same checks, in the same order, as the pure-Python
 * reference (robocli/protocols/scip2/replies.py), so both reject the same inputs.
 *
 * The framer (RC_PROTO_SCIP2, in framer.c) finds whole reply blocks:
 *   - a block starts with an echo line of 1..64 printable chars, then a status line of
 *     3 chars (2 + their sum) or 1 char (SCIP 1.1, the SCIP2.0 switch), and runs to the
 *     first empty line; a CR just before an LF is tolerated, anywhere else it is garbage;
 *   - outside a block an empty line is dropped; a non-printable byte ends the candidate
 *     (dropped with everything before it); a candidate with a bad status line, a garbage
 *     byte or a line over 128 chars in its body, or longer than max_frame, loses its first
 *     line and the next line is tried as an echo.
 */
#include "robocli_core.h"

#define RC_SCIP_LINE 64u

/* unsigned int carries the uint32 values NumPy hands in */
typedef char rc_scip_uint_is_32_bits[(sizeof(unsigned int) == 4) ? 1 : -1];

unsigned int rc_scip_checksum(const unsigned char *data, size_t n)
{
    unsigned int s = 0;
    size_t i;

    for (i = 0; i < n; i++) {
        s += data[i];
    }
    return (s & 0x3Fu) + 0x30u;
}

int rc_scip_decode(const unsigned char *data, size_t n, int width, int check,
                   unsigned int *out, size_t count, size_t *err_at)
{
    size_t p = 0, chars = 0, k = 0, v = 0;
    unsigned int acc = 0;
    int fill = 0;

    *err_at = 0;
    if (width < 2 || width > 4) {
        return RC_SCIP_ECOUNT;
    }
    /* pass 1: the lines, in order: garbage, length, sum */
    while (p < n) {
        size_t i = p, end, d;
        while (i < n && data[i] != '\n') {
            unsigned char c = data[i];
            if ((c < 0x20 || c > 0x7E) && !(c == '\r' && i + 1 < n && data[i + 1] == '\n')) {
                *err_at = i;
                return RC_SCIP_EGARBAGE;
            }
            i++;
        }
        *err_at = p;
        if (i >= n) {
            return RC_SCIP_ELINE; /* no LF */
        }
        end = (i > p && data[i - 1] == '\r') ? i - 1 : i;
        d = end - p; /* chars + sum */
        if (d < 2 || d - 1 > RC_SCIP_LINE || (i + 1 < n && d - 1 != RC_SCIP_LINE)) {
            return RC_SCIP_ELINE;
        }
        if (check && rc_scip_checksum(data + p, d - 1) != data[end - 1]) {
            return RC_SCIP_ECHECKSUM;
        }
        chars += d - 1;
        p = i + 1;
    }
    *err_at = n;
    if (chars != count * (size_t)width || (count != 0 && chars / (size_t)width != count)) {
        return RC_SCIP_ECOUNT;
    }
    /* pass 2: the values, skipping each line's sum char and end */
    p = 0;
    while (v < count) {
        size_t lend = p;
        while (data[lend] != '\n') {
            lend++;
        }
        if (lend > p && data[lend - 1] == '\r') {
            lend--;
        }
        lend--; /* the sum char */
        for (k = p; k < lend; k++) {
            unsigned int c = data[k];
            if (c < 0x30u || c > 0x6Fu) {
                *err_at = k;
                return RC_SCIP_ECHAR;
            }
            acc = (acc << 6) | (c - 0x30u);
            if (++fill == width) {
                out[v++] = acc;
                acc = 0;
                fill = 0;
            }
        }
        while (data[p] != '\n') {
            p++;
        }
        p++;
    }
    return RC_SCIP_OK;
}
