/*
 * C tests of the robocli core: ./test_core SPECDIR
 *
 * Checks the ARCOS checksum vectors, every golden frame vector of SPECDIR/ *.json (one
 * vector object per line with "framer" and "hex" keys) under chunking and garbage, the
 * ring buffer, alignment and the ping-pong floor. Last line: "N passed, M failed".
 *
 * The golden vectors cannot pass vacuously: each spec file declares its number of vectors
 * on a top-level line '"count": N,' and the suite fails when SPECDIR cannot be read, holds
 * no spec file, a file has no count, no vectors, or not exactly N vector lines, or when a
 * framer (arcos, sm-le, sm-be, ros4mat) has no vector at all.
 *
 * ./test_core --specs-only SPECDIR runs the golden-vector checks alone.
 */
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "robocli_core.h"

#include "check.h"

/* ------------------------------------------------------------------ helpers */

static unsigned long rng_state = 12345UL;

static unsigned long rnd(void)
{
    rng_state = (rng_state * 1103515245UL + 12345UL) & 0xFFFFFFFFUL;
    return (rng_state >> 8) & 0xFFFFFFUL;
}

static size_t parse_hex(const char *s, size_t slen, unsigned char *out)
{
    size_t n = 0;
    int half = -1;
    size_t i;

    for (i = 0; i < slen; i++) {
        int c = s[i];
        int v;
        if (c >= '0' && c <= '9') {
            v = c - '0';
        } else if (c >= 'a' && c <= 'f') {
            v = c - 'a' + 10;
        } else if (c >= 'A' && c <= 'F') {
            v = c - 'A' + 10;
        } else {
            continue;
        }
        if (half < 0) {
            half = v;
        } else {
            out[n++] = (unsigned char)(half * 16 + v);
            half = -1;
        }
    }
    return n;
}

static int kind_proto(const char *kind)
{
    if (strcmp(kind, "arcos") == 0) {
        return RC_PROTO_ARCOS;
    }
    if (strcmp(kind, "sm-le") == 0) {
        return RC_PROTO_SM_LE;
    }
    if (strcmp(kind, "sm-be") == 0) {
        return RC_PROTO_SM_BE;
    }
    if (strcmp(kind, "ros4mat") == 0) {
        return RC_PROTO_ROS4MAT;
    }
    if (strcmp(kind, "scip2") == 0) {
        return RC_PROTO_SCIP2;
    }
    return 0;
}

static unsigned long le32(const unsigned char *p)
{
    return (unsigned long)p[0] | ((unsigned long)p[1] << 8) | ((unsigned long)p[2] << 16) |
           ((unsigned long)p[3] << 24);
}

/* Oracle, written independently of framer.c: could a frame start at p (header complete)? */
static int plausible(int proto, const unsigned char *p, size_t avail)
{
    unsigned long v;
    if (proto == RC_PROTO_ARCOS) {
        return avail >= 1 && p[0] == 0xFA;
    }
    if (proto == RC_PROTO_SCIP2) { /* anything but a non-printable byte may join a line */
        return avail >= 1 && ((p[0] >= 0x20 && p[0] <= 0x7E) || p[0] == '\n' || p[0] == '\r');
    }
    if (proto == RC_PROTO_SM_LE || proto == RC_PROTO_SM_BE) {
        if (avail < 4) {
            return 1;
        }
        v = proto == RC_PROTO_SM_LE
                ? le32(p)
                : ((unsigned long)p[0] << 24) | ((unsigned long)p[1] << 16) |
                      ((unsigned long)p[2] << 8) | (unsigned long)p[3];
        return v >= 12 && v <= 4096;
    }
    if (avail < 27) {
        return 1;
    }
    if (p[18] > 1) {
        return 0;
    }
    if (p[18] == 0 && p[1] == 0 && le32(p + 6) != 0 && le32(p + 14) != le32(p + 10)) {
        return 0;
    }
    v = (p[1] != 0 || le32(p + 6) != 0) ? le32(p + 14) : 0;
    return v <= 16UL * 1024UL * 1024UL;
}

/* Feed `data` in chunks (chunk 0: random sizes 1..maxchunk), collect frames. Returns the
 * number of frames; checks each against the expected list in order. */
static unsigned long run_stream(rc_framer *f, const unsigned char *data, size_t n,
                                size_t chunk, size_t maxchunk, unsigned char **exp,
                                size_t *explen, size_t nexp, int *mismatch)
{
    size_t off = 0;
    unsigned long got = 0;
    const unsigned char *fr;
    size_t len;

    *mismatch = 0;
    while (off < n) {
        size_t k = chunk != 0 ? chunk : 1 + rnd() % maxchunk;
        if (k > n - off) {
            k = n - off;
        }
        if (rc_framer_feed(f, data + off, k) != 0) {
            *mismatch = 1;
            return got;
        }
        off += k;
        while (rc_framer_next(f, &fr, &len)) {
            if (got >= nexp || len != explen[got] || memcmp(fr, exp[got], len) != 0) {
                *mismatch = 1;
            }
            got++;
        }
    }
    return got;
}

/* ------------------------------------------------------------------ checksum */

static const char *arcos_vectors[] = {
    "FA FB 03 00 00 00",
    "FA FB 03 01 00 01",
    "FA FB 03 02 00 02",
    "FA FB 06 01 3B 01 00 02 3B",
    "FA FB 06 04 3B 01 00 05 3B",
    "FA FB 06 0B 3B C8 00 D3 3B",
    "FA FB 06 0B 1B C8 00 D3 1B",
    "FA FB 06 02 3B 01 00 03 3B",
    "FA FB 1A 02 4D 6F 62 69 6C 65 53 69 6D 00 50 69 6F 6E 65 65 72 00 70 33 64 78 00 93 45",
};

static void test_checksum(void)
{
    size_t i;
    unsigned char buf[300];
    for (i = 0; i < sizeof(arcos_vectors) / sizeof(arcos_vectors[0]); i++) {
        size_t n = parse_hex(arcos_vectors[i], strlen(arcos_vectors[i]), buf);
        unsigned int want = ((unsigned int)buf[n - 2] << 8) | buf[n - 1];
        CHECK(n == (size_t)buf[2] + 3, "arcos vector length");
        CHECK(rc_arcos_checksum(buf + 3, n - 5) == want, arcos_vectors[i]);
    }
    buf[0] = 0x12;
    buf[1] = 0x34;
    buf[2] = 0xFF;
    buf[3] = 0xFF;
    CHECK(rc_arcos_checksum(buf, 0) == 0, "empty checksum");
    CHECK(rc_arcos_checksum(buf, 1) == 0x12, "odd byte xor");
    CHECK(rc_arcos_checksum(buf, 3) == (0x1234u ^ 0xFFu), "pair then xor");
    CHECK(rc_arcos_checksum(buf + 2, 2) == 0xFFFF, "one pair");
    buf[4] = 0x00;
    buf[5] = 0x02;
    CHECK(rc_arcos_checksum(buf + 2, 4) == 0x0001, "sum wraps mod 65536");
}

/* ------------------------------------------------------------------ framer vectors */

#define MAX_VEC 4096

typedef struct vecset {
    unsigned char *data[MAX_VEC];
    size_t len[MAX_VEC];
    size_t n;
} vecset;

static vecset sets[6];

/* Feed `data` (n bytes) that completes no frame: then the framer's bad lengths, dropped
 * bytes and pending bytes are as given. */
static void check_no_frame(rc_framer *f, const unsigned char *data, size_t n,
                           unsigned long bad_lengths, unsigned long dropped, size_t pending,
                           const char *what)
{
    const unsigned char *fr;
    size_t len;
    rc_framer_stats st;

    rc_framer_feed(f, data, n);
    CHECK(rc_framer_next(f, &fr, &len) == 0, what);
    rc_framer_get_stats(f, &st);
    CHECK(st.bad_lengths == bad_lengths && st.dropped_bytes == dropped &&
              rc_framer_pending(f) == pending,
          what);
}

static void test_one_vector(int proto, const unsigned char *v, size_t vlen, const char *name)
{
    rc_framer *f = rc_framer_new(proto, 0);
    rc_framer_stats st;
    unsigned char *exp[1];
    size_t explen[1];
    unsigned char *buf;
    size_t gb, ga, i, total;
    int mismatch, trial, ok;
    unsigned long got;
    size_t chunks[4];

    exp[0] = (unsigned char *)v;
    explen[0] = vlen;
    CHECK(f != NULL, "framer_new");
    if (f == NULL) {
        return;
    }
    chunks[0] = 0;
    chunks[1] = 1;
    chunks[2] = 2;
    chunks[3] = 3;
    /* whole, random chunks, byte by byte */
    for (trial = 0; trial < 8; trial++) {
        size_t chunk = trial < 4 ? (trial == 0 ? vlen : chunks[trial]) : 0;
        rc_framer_free(f);
        f = rc_framer_new(proto, 0);
        got = run_stream(f, v, vlen, chunk, 1 + vlen / 2, exp, explen, 1, &mismatch);
        rc_framer_get_stats(f, &st);
        CHECK(got == 1 && !mismatch, name);
        CHECK(st.frames == 1 && st.dropped_bytes == 0 && rc_framer_pending(f) == 0, name);
    }
    /* garbage before and after */
    buf = (unsigned char *)malloc(vlen + 200);
    for (trial = 0; trial < 12; trial++) {
        int attempt;
        gb = rnd() % 40;
        ga = rnd() % 40;
        ok = 0;
        for (attempt = 0; attempt < 12 && !ok; attempt++) {
            for (i = 0; i < gb; i++) {
                unsigned char c = attempt < 10 ? (unsigned char)(rnd() & 0xFF) : 0xFF;
                if (proto == RC_PROTO_ARCOS && c == 0xFA) {
                    c = 0xFF;
                }
                buf[i] = c;
            }
            memcpy(buf + gb, v, vlen);
            ok = 1;
            for (i = 0; i < gb; i++) {
                if (plausible(proto, buf + i, gb + vlen - i)) {
                    ok = 0;
                    break;
                }
            }
        }
        if (!ok) {
            gb = 0;
            memcpy(buf, v, vlen);
        }
        for (i = 0; i < ga; i++) {
            buf[gb + vlen + i] = 0xFF;
        }
        total = gb + vlen + ga;
        rc_framer_free(f);
        f = rc_framer_new(proto, 0);
        got = run_stream(f, buf, total, 0, 1 + total / 3, exp, explen, 1, &mismatch);
        rc_framer_get_stats(f, &st);
        CHECK(got == 1 && !mismatch && st.frames == 1, name);
        if (proto == RC_PROTO_ARCOS) {
            CHECK(st.dropped_bytes == gb + ga && rc_framer_pending(f) == 0, name);
        } else {
            CHECK(st.dropped_bytes >= gb && st.dropped_bytes + rc_framer_pending(f) == gb + ga,
                  name);
        }
    }
    /* ARCOS: a flipped checksum bit is rejected */
    if (proto == RC_PROTO_ARCOS) {
        memcpy(buf, v, vlen);
        buf[vlen - 1] ^= 0x01;
        rc_framer_free(f);
        f = rc_framer_new(proto, 0);
        got = run_stream(f, buf, vlen, vlen, 1, exp, explen, 0, &mismatch);
        rc_framer_get_stats(f, &st);
        CHECK(got == 0 && st.bad_checksums == 1 && st.dropped_bytes == vlen, name);
    }
    free(buf);
    rc_framer_free(f);
}

static void test_concat(int proto, vecset *vs)
{
    size_t total = 0, i, off = 0;
    unsigned char *buf;
    int trial, mismatch;
    unsigned long got;
    rc_framer *f;

    if (vs->n == 0) {
        return;
    }
    for (i = 0; i < vs->n; i++) {
        total += vs->len[i];
    }
    buf = (unsigned char *)malloc(total);
    for (i = 0; i < vs->n; i++) {
        memcpy(buf + off, vs->data[i], vs->len[i]);
        off += vs->len[i];
    }
    for (trial = 0; trial < 6; trial++) {
        f = rc_framer_new(proto, 0);
        got = run_stream(f, buf, total, trial == 0 ? total : (trial == 1 ? 1 : 0), 64,
                         vs->data, vs->len, vs->n, &mismatch);
        CHECK(got == vs->n && !mismatch && rc_framer_pending(f) == 0, "concatenated vectors");
        rc_framer_free(f);
    }
    free(buf);
}

static char *find_value(char *line, const char *key, size_t *vlen)
{
    char *p = strstr(line, key);
    char *q;
    if (p == NULL) {
        return NULL;
    }
    p += strlen(key);
    while (*p == ' ' || *p == '\t') {
        p++;
    }
    if (*p != ':') {
        return NULL;
    }
    p++;
    while (*p == ' ' || *p == '\t') {
        p++;
    }
    if (*p != '"') {
        return NULL;
    }
    p++;
    q = strchr(p, '"');
    if (q == NULL) {
        return NULL;
    }
    *vlen = (size_t)(q - p);
    return p;
}

/* The declared count of a top-level '"count": N' line (first key on its line), else -1. */
static long count_line(const char *line)
{
    const char *p = line;
    long v = 0;
    int digits = 0;
    while (*p == ' ' || *p == '\t') {
        p++;
    }
    if (strncmp(p, "\"count\"", 7) != 0) {
        return -1;
    }
    p += 7;
    while (*p == ' ' || *p == '\t') {
        p++;
    }
    if (*p != ':') {
        return -1;
    }
    p++;
    while (*p == ' ' || *p == '\t') {
        p++;
    }
    while (*p >= '0' && *p <= '9' && digits < 9) {
        v = v * 10 + (*p - '0');
        p++;
        digits++;
    }
    return digits > 0 ? v : -1;
}

static int load_file(const char *path)
{
    FILE *fp = fopen(path, "rb");
    char *line;
    size_t cap = 1 << 16, n;
    int c, count = 0, lost = 0;
    long declared = -1, v;

    if (fp == NULL) {
        fprintf(stderr, "cannot open %s\n", path);
        n_fail++;
        return 0;
    }
    line = (char *)malloc(cap);
    for (;;) {
        char *kind, *hex;
        size_t klen, hlen;
        char kbuf[16];
        int proto;
        n = 0;
        while ((c = fgetc(fp)) != EOF && c != '\n') {
            if (n + 1 >= cap) {
                cap *= 2;
                line = (char *)realloc(line, cap);
            }
            line[n++] = (char)c;
        }
        line[n] = '\0';
        v = count_line(line);
        if (v >= 0) {
            CHECK(declared < 0, "one top-level count per spec file");
            declared = v;
        }
        kind = find_value(line, "\"framer\"", &klen);
        hex = find_value(line, "\"hex\"", &hlen);
        if (kind != NULL && hex != NULL) {
            vecset *vs;
            if (klen >= sizeof(kbuf)) {
                klen = sizeof(kbuf) - 1;
            }
            memcpy(kbuf, kind, klen);
            kbuf[klen] = '\0';
            proto = kind_proto(kbuf);
            CHECK(proto != 0, "known framer kind in spec file");
            if (proto != 0) {
                vs = &sets[proto];
                if (vs->n < MAX_VEC) {
                    vs->data[vs->n] = (unsigned char *)malloc(hlen / 2 + 1);
                    vs->len[vs->n] = parse_hex(hex, hlen, vs->data[vs->n]);
                    vs->n++;
                    count++;
                } else {
                    lost++;
                }
            }
        }
        if (c == EOF) {
            break;
        }
    }
    free(line);
    fclose(fp);
    if (declared < 0) {
        fprintf(stderr, "FAIL %s: no top-level \"count\" line\n", path);
    } else if (declared != (long)count || lost != 0) {
        fprintf(stderr, "FAIL %s: declares %ld vectors, %d found (%d over capacity)\n", path,
                declared, count, lost);
    }
    CHECK(declared >= 0, "spec file declares its vector count");
    CHECK(declared > 0 && declared == (long)count && lost == 0,
          "spec file holds exactly its declared number of vectors");
    return count;
}

/* ------------------------------------------------------------------ SCIP 2.0 */

/* decimal field of `w` digits at p, -1 if not digits */
static long scip_digits(const unsigned char *p, int w)
{
    long v = 0;
    int i;
    for (i = 0; i < w; i++) {
        if (p[i] < '0' || p[i] > '9') {
            return -1;
        }
        v = v * 10 + (p[i] - '0');
    }
    return v;
}

/* offset just after the k-th LF of v (0 if there are fewer) */
static size_t scip_after_lf(const unsigned char *v, size_t n, int k)
{
    size_t i;
    for (i = 0; i < n; i++) {
        if (v[i] == '\n' && --k == 0) {
            return i + 1;
        }
    }
    return 0;
}

/* The scan vectors of specs/scip2.json decoded whole: G8 (1000, 5432, 0), G11 ME pairs
 * ((1000, 300), (2000, 4000)), G12/G13 (1000 + step). Then the same data corrupted. */
static void test_scip_vectors(const vecset *vs)
{
    size_t i, j, nscan = 0;
    unsigned int out[2048];

    for (i = 0; i < vs->n; i++) {
        const unsigned char *v = vs->data[i];
        size_t n = vs->len[i], at, err_at;
        long start, end, cluster, count;
        int per, ok = 1, rc;
        unsigned char *bad;

        if (n < 16 || !(v[0] == 'G' || v[0] == 'M') || !(v[1] == 'D' || v[1] == 'E')) {
            continue;
        }
        at = scip_after_lf(v, n, 3);
        if (at == 0 || at >= n) {
            continue; /* a status-only reply (laser off, MD ack) */
        }
        start = scip_digits(v + 2, 4);
        end = scip_digits(v + 6, 4);
        cluster = scip_digits(v + 10, 2);
        per = v[1] == 'E' ? 2 : 1;
        count = (end - start + (cluster > 1 ? cluster : 1)) / (cluster > 1 ? cluster : 1) * per;
        CHECK(start >= 0 && end >= start && count > 0 && count <= 2048, "scip vector echo");
        rc = rc_scip_decode(v + at, n - at - 1, 3, 1, out, (size_t)count, &err_at);
        CHECK(rc == RC_SCIP_OK, "scip vector decodes");
        CHECK(rc_scip_checksum(v + at - 6, 4) == v[at - 2], "scip timestamp line sum");
        for (j = 0; rc == RC_SCIP_OK && j < (size_t)count; j++) {
            unsigned int want;
            if (count == 3) {
                want = j == 0 ? 1000u : (j == 1 ? 5432u : 0u);
            } else if (per == 2) {
                want = j == 0 ? 1000u : (j == 1 ? 300u : (j == 2 ? 2000u : 4000u));
            } else {
                want = 1000u + (unsigned int)start + (unsigned int)j;
            }
            ok = ok && out[j] == want;
        }
        CHECK(ok, "scip vector values");
        nscan++;
        /* one value too many or too few expected: the count is checked */
        CHECK(rc_scip_decode(v + at, n - at - 1, 3, 1, out, (size_t)count - 1, &err_at) ==
                  RC_SCIP_ECOUNT, "scip count short");
        CHECK(rc_scip_decode(v + at, n - at - 1, 3, 1, out, (size_t)count + 1, &err_at) ==
                  RC_SCIP_ECOUNT, "scip count long");
        CHECK(rc_scip_decode(v + at, n - at - 1, 2, 1, out, 2048, &err_at) == RC_SCIP_ECOUNT,
              "scip wrong width");
        /* a truncated block: the region cut inside its last line */
        CHECK(rc_scip_decode(v + at, n - at - 3, 3, 1, out, (size_t)count, &err_at) ==
                  RC_SCIP_ELINE, "scip truncated line");
        bad = (unsigned char *)malloc(n);
        memcpy(bad, v, n);
        bad[at] = bad[at] == '0' ? '1' : '0'; /* first data char: the line's sum fails */
        CHECK(rc_scip_decode(bad + at, n - at - 1, 3, 1, out, (size_t)count, &err_at) ==
                  RC_SCIP_ECHECKSUM && err_at == 0, "scip bad sum");
        CHECK(rc_scip_decode(bad + at, n - at - 1, 3, 0, out, (size_t)count, &err_at) ==
                  RC_SCIP_OK, "scip sums not checked");
        bad[at] = 0x01;
        CHECK(rc_scip_decode(bad + at, n - at - 1, 3, 0, out, (size_t)count, &err_at) ==
                  RC_SCIP_EGARBAGE, "scip garbage byte");
        bad[at] = 'p'; /* past 'o' */
        CHECK(rc_scip_decode(bad + at, n - at - 1, 3, 0, out, (size_t)count, &err_at) ==
                  RC_SCIP_ECHAR && err_at == 0, "scip bad char");
        free(bad);
    }
    CHECK(nscan > 0, "scip scan vectors found (G8, G11, G12, G13 in specs/)");
}

/* Random corruption of the scan vectors, in exact-size heap buffers (so that ASan sees any
 * read or write past them): 1-3 bytes replaced (LF, CR and garbage likely), or the region
 * cut short. The decoder must return a code and stay inside its buffers; the framer, fed the
 * whole mutated reply in random chunks, must keep its counters consistent. */
static void test_scip_mutations(const vecset *vs)
{
    static const unsigned char picks[] = {'\n', '\r', '0', 'o', 'p', 0x00, 0xFF, ';', ' '};
    size_t i, trial, runs = 0;

    for (i = 0; i < vs->n; i++) {
        const unsigned char *v = vs->data[i];
        size_t n = vs->len[i], at, count;
        long start, end;

        if (n < 16 || !(v[0] == 'G' || v[0] == 'M') || !(v[1] == 'D' || v[1] == 'E')) {
            continue;
        }
        at = scip_after_lf(v, n, 3);
        if (at == 0 || at >= n) {
            continue;
        }
        start = scip_digits(v + 2, 4);
        end = scip_digits(v + 6, 4);
        count = (size_t)(end - start + 1) * (v[1] == 'E' ? 2u : 1u);
        for (trial = 0; trial < 3000; trial++) {
            size_t len = n - at - 1, k, err_at = 0, off = 0, flen;
            unsigned char *region = (unsigned char *)malloc(len);
            unsigned int *out = (unsigned int *)malloc(count * sizeof(unsigned int));
            unsigned char *whole = (unsigned char *)malloc(n);
            rc_framer *f = rc_framer_new(RC_PROTO_SCIP2, 0);
            rc_framer_stats st;
            const unsigned char *fr;
            int rc, nmut = 1 + (int)(rnd() % 3);

            memcpy(region, v + at, len);
            for (k = 0; k < (size_t)nmut; k++) {
                size_t pos = rnd() % len;
                region[pos] = rnd() % 2 ? picks[rnd() % sizeof(picks)] : (unsigned char)rnd();
            }
            if (trial % 5 == 0) {
                len = rnd() % len; /* cut short */
            }
            rc = rc_scip_decode(region, len, 3, (int)(trial % 2), out, count, &err_at);
            CHECK(rc >= RC_SCIP_OK && rc <= RC_SCIP_ECHAR && err_at <= len, "scip mutation code");
            memcpy(whole, v, at);
            memcpy(whole + at, region, n - at - 1 < len ? n - at - 1 : len);
            flen = at + (n - at - 1 < len ? n - at - 1 : len);
            while (off < flen) {
                size_t chunk = 1 + rnd() % 97;
                if (chunk > flen - off) {
                    chunk = flen - off;
                }
                rc_framer_feed(f, whole + off, chunk);
                off += chunk;
                while (rc_framer_next(f, &fr, &k)) {
                    CHECK(k >= 6 && fr[k - 1] == '\n', "scip mutated frame ends in LF");
                }
            }
            rc_framer_get_stats(f, &st);
            CHECK(st.dropped_bytes + rc_framer_pending(f) <= flen, "scip mutated stream counts");
            rc_framer_free(f);
            free(whole);
            free(out);
            free(region);
            runs++;
        }
    }
    CHECK(runs > 0, "scip mutations ran");
}

/* SCIP framer units: resync after garbage lines, a bad status sum, CR LF, max_frame. */
static void test_scip_framer(void)
{
    static const char g8[] = "GD0384038601\n00P\n00?Xg\n0?X1Dh000d\n\n";
    static const char junk[] = "\x01\xffnoise\nxx\n0@D0@E\n\n";
    static const char badst[] = "QT\n00Q\n\n";
    static const char crlf[] = "\r\nBM\r\n00P\r\n\r\n";
    unsigned char buf[512];
    size_t n = 0, len, g8n = sizeof(g8) - 1;
    const unsigned char *fr;
    rc_framer *f = rc_framer_new(RC_PROTO_SCIP2, 0);
    rc_framer_stats st;
    int frames = 0;
    unsigned char big[600];

    CHECK(rc_scip_checksum((const unsigned char *)"00", 2) == 'P', "scip sum 00");
    CHECK(rc_scip_checksum((const unsigned char *)"99", 2) == 'b', "scip sum 99");
    memcpy(buf + n, junk, sizeof(junk) - 1);
    n += sizeof(junk) - 1;
    memcpy(buf + n, g8, g8n);
    n += g8n;
    memcpy(buf + n, badst, sizeof(badst) - 1);
    n += sizeof(badst) - 1;
    memcpy(buf + n, g8, g8n);
    n += g8n;
    rc_framer_feed(f, buf, n);
    while (rc_framer_next(f, &fr, &len)) {
        CHECK(len == g8n && memcmp(fr, g8, g8n) == 0, "scip frame after garbage");
        frames++;
    }
    rc_framer_get_stats(f, &st);
    CHECK(frames == 2 && st.frames == 2 && st.bad_checksums == 1, "scip resync");
    CHECK(st.dropped_bytes == sizeof(junk) - 1 + sizeof(badst) - 1 && rc_framer_pending(f) == 0,
          "scip dropped bytes counted");
    rc_framer_feed(f, (const unsigned char *)crlf, sizeof(crlf) - 1);
    CHECK(rc_framer_next(f, &fr, &len) && len == sizeof(crlf) - 3, "scip CR LF block");
    rc_framer_free(f);
    /* a block that never ends is cut at max_frame */
    f = rc_framer_new(RC_PROTO_SCIP2, 256);
    memset(big, '0', sizeof(big));
    memcpy(big, "MD0044072501000\n99b\n", 20);
    for (n = 20 + 65; n + 1 < sizeof(big); n += 66) {
        big[n] = '\n';
    }
    big[sizeof(big) - 1] = '\n';
    rc_framer_feed(f, big, sizeof(big));
    CHECK(!rc_framer_next(f, &fr, &len), "scip runaway block");
    rc_framer_get_stats(f, &st);
    CHECK(st.bad_lengths >= 1 && rc_framer_pending(f) <= 256, "scip runaway block dropped");
    rc_framer_feed(f, (const unsigned char *)g8, g8n);
    CHECK(rc_framer_next(f, &fr, &len) && len == g8n, "scip frame after a runaway block");
    rc_framer_free(f);
    CHECK(rc_framer_new(RC_PROTO_SCIP2, 7) == NULL, "scip max_frame minimum");
}

static void test_spec_vectors(const char *dir)
{
    DIR *d = dir != NULL ? opendir(dir) : NULL;
    struct dirent *e;
    int nfiles = 0, nvec = 0, proto;
    size_t i;
    char path[4096];
    char name[64];

    if (d == NULL) {
        fprintf(stderr, "FAIL cannot open spec directory %s: no golden vectors tested\n",
                dir != NULL ? dir : "(none; usage: test_core [--specs-only] SPECDIR)");
        n_fail++;
        return;
    }
    while ((e = readdir(d)) != NULL) {
        size_t L = strlen(e->d_name);
        if (L > 5 && strcmp(e->d_name + L - 5, ".json") == 0) {
            sprintf(path, "%.4000s/%.90s", dir, e->d_name);
            nvec += load_file(path);
            nfiles++;
        }
    }
    closedir(d);
    if (nfiles == 0 || nvec == 0) {
        fprintf(stderr, "FAIL %d spec files, %d golden frame vectors in %s\n", nfiles, nvec,
                dir);
    }
    CHECK(nfiles > 0 && nvec > 0, "golden vectors found in the spec directory");
    for (proto = 1; proto <= 5; proto++) {
        if (sets[proto].n == 0) {
            fprintf(stderr, "FAIL no golden vector for framer %d in %s\n", proto, dir);
        }
        CHECK(sets[proto].n > 0, "golden vectors for every framer");
    }
    test_scip_vectors(&sets[RC_PROTO_SCIP2]);
    test_scip_mutations(&sets[RC_PROTO_SCIP2]);
    for (proto = 1; proto <= 5; proto++) {
        for (i = 0; i < sets[proto].n; i++) {
            sprintf(name, "spec vector proto %d #%lu", proto, (unsigned long)i);
            test_one_vector(proto, sets[proto].data[i], sets[proto].len[i], name);
        }
        test_concat(proto, &sets[proto]);
        for (i = 0; i < sets[proto].n; i++) {
            free(sets[proto].data[i]);
        }
    }
    printf("golden vectors: %d files, %lu arcos, %lu sm-le, %lu sm-be, %lu ros4mat, %lu scip2\n",
           nfiles, (unsigned long)sets[1].n, (unsigned long)sets[2].n, (unsigned long)sets[3].n,
           (unsigned long)sets[4].n, (unsigned long)sets[5].n);
}

/* ------------------------------------------------------------------ framer units */

static void test_framer_units(void)
{
    unsigned char buf[600];
    unsigned char frame[300];
    size_t n, i;
    rc_framer *f;
    rc_framer_stats st;
    const unsigned char *fr;
    size_t len;
    unsigned long cnt;

    /* built-in ARCOS vectors through the framer, after FA FA and FA 00 FB noise */
    for (i = 0; i < sizeof(arcos_vectors) / sizeof(arcos_vectors[0]); i++) {
        unsigned char *e[1];
        size_t el[1];
        int mm;
        buf[0] = 0xFA;
        buf[1] = 0xFA;
        buf[2] = 0x00;
        buf[3] = 0xFA;
        n = 4 + parse_hex(arcos_vectors[i], strlen(arcos_vectors[i]), buf + 4);
        e[0] = buf + 4;
        el[0] = n - 4;
        f = rc_framer_new(RC_PROTO_ARCOS, 0);
        cnt = run_stream(f, buf, n, 0, 5, e, el, 1, &mm);
        rc_framer_get_stats(f, &st);
        CHECK(cnt == 1 && !mm && st.dropped_bytes == 4, "arcos FA FA FB resync");
        rc_framer_free(f);
    }
    /* ARCOS count out of range */
    f = rc_framer_new(RC_PROTO_ARCOS, 0);
    buf[0] = 0xFA;
    buf[1] = 0xFB;
    buf[2] = 0x02;
    check_no_frame(f, buf, 3, 1, 3, 0, "arcos bad count");
    rc_framer_free(f);
    /* ARCOS max_frame */
    f = rc_framer_new(RC_PROTO_ARCOS, 8);
    n = parse_hex(arcos_vectors[3], strlen(arcos_vectors[3]), buf);
    check_no_frame(f, buf, n, 1, n, 0, "arcos max_frame");
    rc_framer_free(f);
    CHECK(rc_framer_new(99, 0) == NULL, "bad protocol");
    CHECK(rc_framer_new(RC_PROTO_SM_LE, 10) == NULL, "max_frame too small");
    CHECK(rc_framer_new(0, 0) == NULL && rc_framer_new(RC_PROTO_SCIP2 + 1, 0) == NULL,
          "protocols just outside the table");
    {
        /* each protocol's smallest frame: one byte less is refused */
        static const int protos[] = {RC_PROTO_ARCOS, RC_PROTO_SM_LE, RC_PROTO_SM_BE,
                                     RC_PROTO_ROS4MAT, RC_PROTO_SCIP2};
        static const size_t mins[] = {6, 16, 16, 27, 8};
        for (i = 0; i < 5; i++) {
            f = rc_framer_new(protos[i], mins[i]);
            CHECK(f != NULL && rc_framer_new(protos[i], mins[i] - 1) == NULL, "smallest frame");
            rc_framer_free(f);
        }
    }

    /* Simple Message LE and BE, length 12 + 8 body */
    for (i = 0; i < 2; i++) {
        int proto = i == 0 ? RC_PROTO_SM_LE : RC_PROTO_SM_BE;
        memset(frame, 0, 24);
        if (proto == RC_PROTO_SM_LE) {
            frame[0] = 20;
        } else {
            frame[3] = 20;
        }
        frame[4] = 10;
        frame[8] = 1;
        f = rc_framer_new(proto, 0);
        rc_framer_feed(f, frame, 23);
        CHECK(rc_framer_next(f, &fr, &len) == 0 && rc_framer_pending(f) == 23, "sm partial");
        rc_framer_feed(f, frame + 23, 1);
        CHECK(rc_framer_next(f, &fr, &len) == 1 && len == 24 && memcmp(fr, frame, 24) == 0,
              "sm frame");
        /* 0xFF garbage is rejected one byte at a time */
        memset(buf, 0xFF, 8);
        rc_framer_feed(f, buf, 8);
        rc_framer_feed(f, frame, 24);
        CHECK(rc_framer_next(f, &fr, &len) == 1 && len == 24 && memcmp(fr, frame, 24) == 0,
              "sm resync");
        rc_framer_get_stats(f, &st);
        CHECK(st.frames == 2 && st.dropped_bytes == 8 && st.bad_lengths == 8, "sm stats");
        /* a length of 11 is rejected */
        memset(buf, 0, 4);
        buf[proto == RC_PROTO_SM_LE ? 0 : 3] = 11;
        rc_framer_feed(f, buf, 4);
        CHECK(rc_framer_next(f, &fr, &len) == 0 && rc_framer_pending(f) == 3, "sm length 11");
        rc_framer_get_stats(f, &st);
        CHECK(st.bad_lengths == 9, "sm length 11 counted");
        rc_framer_free(f);
    }

    /* ros4mat: a data reply with 2 records of 5 bytes, an error reply, a pull */
    memset(frame, 0, 64);
    frame[0] = 0x20;
    frame[6] = 2;
    frame[10] = 10;
    frame[14] = 10;
    for (i = 27; i < 37; i++) {
        frame[i] = (unsigned char)i;
    }
    f = rc_framer_new(RC_PROTO_ROS4MAT, 0);
    rc_framer_feed(f, frame, 36);
    CHECK(rc_framer_next(f, &fr, &len) == 0, "r4m partial");
    rc_framer_feed(f, frame + 36, 1);
    CHECK(rc_framer_next(f, &fr, &len) == 1 && len == 37, "r4m data frame");
    memset(buf, 0, 40);
    buf[0] = 0x13;
    buf[1] = 1;
    buf[14] = 4;
    buf[27] = 'b';
    buf[28] = 'a';
    buf[29] = 'd';
    rc_framer_feed(f, buf, 31);
    CHECK(rc_framer_next(f, &fr, &len) == 1 && len == 31, "r4m error frame");
    memset(buf, 0, 40);
    buf[0] = 0x20;
    buf[14] = 99; /* size 0: no body whatever compressSize says */
    rc_framer_feed(f, buf, 27);
    CHECK(rc_framer_next(f, &fr, &len) == 1 && len == 27, "r4m pull");
    buf[18] = 2; /* bad compression type */
    check_no_frame(f, buf, 27, 1, 1, 26, "r4m bad header");
    rc_framer_reset(f);
    CHECK(rc_framer_pending(f) == 0, "reset");
    rc_framer_free(f);

    /* count API and a long stream through a growing buffer */
    {
        size_t nf = 5000, fl = 89, k;
        unsigned char *s = (unsigned char *)malloc(nf * fl);
        unsigned int ck;
        for (k = 0; k < nf; k++) {
            unsigned char *p = s + k * fl;
            p[0] = 0xFA;
            p[1] = 0xFB;
            p[2] = 0x56;
            p[3] = 0x32;
            for (i = 4; i < fl - 2; i++) {
                p[i] = (unsigned char)(rnd() & 0xFF);
            }
            ck = rc_arcos_checksum(p + 3, fl - 5);
            p[fl - 2] = (unsigned char)(ck >> 8);
            p[fl - 1] = (unsigned char)(ck & 0xFF);
        }
        for (k = 0; k < 4; k++) {
            size_t chunk = k == 0 ? 0 : (k == 1 ? 1 : (k == 2 ? 7 : 10000));
            f = rc_framer_new(RC_PROTO_ARCOS, 0);
            cnt = rc_framer_count(f, s, nf * fl, chunk);
            CHECK(cnt == nf && rc_framer_pending(f) == 0, "count SIP stream");
            rc_framer_free(f);
        }
        free(s);
    }
}

/* ------------------------------------------------------------------ ring */

static void test_ring(void)
{
    rc_ring *r = rc_ring_new(4, 8);
    unsigned char rec[4];
    unsigned char out[4 * 64];
    double t[64], tout[64];
    unsigned char recs[4 * 64];
    int a, b, c;
    size_t i, n;
    int ok;

    CHECK(r != NULL && rc_ring_record_size(r) == 4 && rc_ring_capacity(r) == 8, "ring new");
    CHECK(rc_ring_new(0, 8) == NULL && rc_ring_new(4, 0) == NULL, "ring bad sizes");
    a = rc_ring_add_reader(r, 0);
    b = rc_ring_add_reader(r, 3);
    CHECK(a == 0 && b == 1, "reader ids");
    for (i = 0; i < 5; i++) {
        memset(rec, (int)i, 4);
        rc_ring_push(r, (double)i, rec);
    }
    CHECK(rc_ring_pushed(r) == 5, "pushed");
    CHECK(rc_ring_available(r, a) == 5 && rc_ring_lost(r, a) == 0, "a avail");
    CHECK(rc_ring_available(r, b) == 3 && rc_ring_lost(r, b) == 2, "b limited");
    n = rc_ring_read(r, b, tout, out, 64);
    CHECK(n == 3 && tout[0] == 2.0 && tout[2] == 4.0 && out[0] == 2 && out[11] == 4, "b read");
    CHECK(rc_ring_available(r, b) == 0 && rc_ring_lost(r, b) == 2, "b after read");
    n = rc_ring_read(r, a, tout, out, 2);
    CHECK(n == 2 && tout[0] == 0.0 && tout[1] == 1.0 && out[4] == 1, "a partial read");
    /* wrap: push 10 more (15 total), a had 3 unread + 10 = 13 > 8 -> lost 5 */
    for (i = 5; i < 15; i++) {
        memset(rec, (int)i, 4);
        rc_ring_push(r, (double)i, rec);
    }
    c = rc_ring_add_reader(r, 100);
    CHECK(c == 2 && rc_ring_available(r, c) == 0, "late reader sees nothing old");
    CHECK(rc_ring_available(r, a) == 8 && rc_ring_lost(r, a) == 5, "a overflow");
    n = rc_ring_read(r, a, tout, out, 64);
    ok = n == 8;
    for (i = 0; i < n; i++) {
        ok = ok && tout[i] == (double)(7 + i) && out[4 * i + 3] == (unsigned char)(7 + i);
    }
    CHECK(ok, "a read across wrap");
    rc_ring_remove_reader(r, b);
    CHECK(rc_ring_available(r, b) == 0 && rc_ring_read(r, b, tout, out, 4) == 0,
          "removed reader");
    CHECK(rc_ring_add_reader(r, 2) == b, "reader slot reused");
    CHECK(rc_ring_available(r, 99) == 0 && rc_ring_lost(r, -1) == 0, "bad reader ids");
    /* push_many, larger than capacity and wrapping */
    for (i = 0; i < 64; i++) {
        t[i] = 100.0 + (double)i;
        memset(recs + 4 * i, (int)(100 + i), 4);
    }
    rc_ring_push_many(r, t, recs, 5);
    n = rc_ring_read(r, c, tout, out, 64);
    CHECK(n == 5 && tout[4] == 104.0 && out[19] == 104, "push_many small");
    rc_ring_push_many(r, t, recs, 20);
    CHECK(rc_ring_pushed(r) == 40, "pushed after push_many");
    n = rc_ring_read(r, c, tout, out, 64);
    ok = n == 8 && rc_ring_lost(r, c) == 12;
    for (i = 0; i < n; i++) {
        ok = ok && tout[i] == 112.0 + (double)i && out[4 * i] == (unsigned char)(112 + i);
    }
    CHECK(ok, "push_many larger than capacity");
    CHECK(rc_ring_available(r, b) == 2 && rc_ring_lost(r, b) == 23, "limit 2 reader");
    n = rc_ring_read(r, b, NULL, NULL, 1);
    CHECK(n == 1 && rc_ring_available(r, b) == 1, "read with NULL outputs");
    rc_ring_free(r);

    /* many pushes vs brute force model: capacity 5, readers with limits 1..5 */
    {
        rc_ring *q = rc_ring_new(1, 5);
        int ids[5];
        unsigned long model_read[5];
        unsigned long pushed = 0;
        size_t k, round;
        unsigned char v;
        ok = 1;
        for (k = 0; k < 5; k++) {
            ids[k] = rc_ring_add_reader(q, k + 1);
            model_read[k] = 0;
        }
        for (round = 0; round < 2000; round++) {
            unsigned long op = rnd() % 3;
            if (op == 0) {
                v = (unsigned char)(pushed & 0xFF);
                rc_ring_push(q, (double)pushed, &v);
                pushed++;
            } else {
                k = rnd() % 5;
                n = rc_ring_read(q, ids[k], tout, out, rnd() % 4);
                {
                    unsigned long first = pushed - model_read[k] > k + 1 ? pushed - (k + 1)
                                                                         : model_read[k];
                    for (i = 0; i < n; i++) {
                        ok = ok && tout[i] == (double)(first + i);
                    }
                    model_read[k] = first + n;
                }
            }
        }
        CHECK(ok, "ring random ops vs model");
        rc_ring_free(q);
    }
}

/* ------------------------------------------------------------------ align */

static void test_align(void)
{
    double ts[] = {0.0, 1.0, 2.0, 2.0, 3.0, 5.0};
    double ref[] = {-1.0, -0.2, 0.5, 1.4, 1.6, 2.0, 2.5, 4.0, 5.0, 5.2, 7.0};
    long want_near[] = {-1, 0, 0, 1, 2, 2, 2, -1, 5, 5, -1};
    long want_lin[] = {-1, -1, 0, 1, 1, 3, 3, 4, 4, -1, -1};
    double want_w[] = {0, 0, 0.5, 0.4, 0.6, 0, 0.5, 0.5, 1.0, 0, 0};
    long idx[11];
    double w[11];
    size_t i;
    int ok = 1;
    double one = 1.0;

    rc_align_nearest(ts, 6, ref, 11, 0.5, idx);
    for (i = 0; i < 11; i++) {
        ok = ok && idx[i] == want_near[i];
    }
    CHECK(ok, "nearest known answers (ties earlier, duplicates earliest)");
    rc_align_nearest(ts, 6, ref, 11, -1.0, idx);
    CHECK(idx[5] == -1 && idx[0] == -1, "negative tol");
    rc_align_nearest(ts, 0, ref, 11, 1.0, idx);
    CHECK(idx[3] == -1, "empty stream nearest");
    rc_align_linear(ts, 6, ref, 11, idx, w);
    ok = 1;
    for (i = 0; i < 11; i++) {
        ok = ok && idx[i] == want_lin[i] && fabs(w[i] - want_w[i]) < 1e-12;
    }
    CHECK(ok, "linear known answers");
    rc_align_linear(&one, 1, ref, 11, idx, w);
    CHECK(idx[0] == -1 && idx[3] == -1, "single sample linear outside");
    rc_align_linear(&one, 1, &one, 1, idx, w);
    CHECK(idx[0] == 0 && w[0] == 0.0, "single sample linear exact");
    rc_align_linear(ts, 0, ref, 11, idx, w);
    CHECK(idx[0] == -1 && w[0] == 0.0, "empty stream linear");
}

/* Informational only (no assertion on wall-clock time): C cost of one rc_ring_push. */
static void time_ring_push(void)
{
    size_t n = 10000000, i;
    rc_ring *r = rc_ring_new(40, 1000000);
    unsigned char rec[40];
    clock_t c0, c1;
    memset(rec, 7, sizeof(rec));
    rc_ring_add_reader(r, 0);
    c0 = clock();
    for (i = 0; i < n; i++) {
        rec[0] = (unsigned char)i;
        rc_ring_push(r, (double)i, rec);
    }
    c1 = clock();
    CHECK(rc_ring_pushed(r) == n, "timed pushes");
    printf("ring push (40-byte records): %.1f ns/record\n",
           (double)(c1 - c0) / CLOCKS_PER_SEC / (double)n * 1e9);
    rc_ring_free(r);
}

/* ------------------------------------------------------------------ pingpong */

static void test_pingpong(void)
{
    double rtt[200];
    size_t i;
    int ok = 1;
    int rc = rc_pingpong_tcp(200, 16, rtt);
    CHECK(rc == 0, "pingpong returns 0");
    if (rc == 0) {
        for (i = 0; i < 200; i++) {
            ok = ok && rtt[i] > 0.0 && rtt[i] < 10.0;
        }
        CHECK(ok, "pingpong RTTs positive");
    }
}

int main(int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "--specs-only") == 0) {
        test_spec_vectors(argc > 2 ? argv[2] : NULL);
        printf("%lu passed, %lu failed\n", n_pass, n_fail);
        return n_fail == 0 ? 0 : 1;
    }
    test_checksum();
    test_framer_units();
    test_scip_framer();
    test_spec_vectors(argc > 1 ? argv[1] : NULL);
    test_ring();
    test_align();
    time_ring_push();
    test_pingpong();
    printf("%lu passed, %lu failed\n", n_pass, n_fail);
    return n_fail == 0 ? 0 : 1;
}
