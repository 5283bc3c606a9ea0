/*
 * Tests of the benchmark peers (benchnet.c) over real loopback sockets: the chunked,
 * optionally pinned ping-pong and the ARCOS responder (table replies, no reply for other
 * frames, a frame split across writes, a second client, a bounded stop).
 * Run by `make test-c` and under ASan/UBSan by `make asan`.
 */
#define _POSIX_C_SOURCE 200112L

#include <stdio.h>
#include <string.h>

#include "robocli_core.h"

#if defined(_WIN32) || !(defined(__unix__) || defined(__APPLE__))

int main(void)
{
    printf("benchmark peers: not supported on this platform\n");
    return 0;
}

#else

#include <unistd.h>
#include <sys/types.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <netinet/in.h>
#include <arpa/inet.h>

#include "check.h"

static void test_pingpong_chunks(void)
{
    double rtt[300];
    size_t i;
    int ok = 1;
    int cpu = rc_pin_supported() ? 0 : -1;
    rc_pingpong *p = rc_pingpong_new(16, cpu);

    CHECK(p != NULL, "ping-pong starts");
    if (p == NULL) {
        return;
    }
    CHECK(rc_pingpong_run(p, 100, cpu, rtt) == 0, "first chunk");
    CHECK(rc_pingpong_run(p, 200, cpu, rtt + 100) == 0, "second chunk, same connection");
    for (i = 0; i < 300; i++) {
        ok = ok && rtt[i] > 0.0 && rtt[i] < 10.0;
    }
    CHECK(ok, "round trips positive");
    if (rc_pin_supported()) {
        CHECK(rc_pingpong_run(p, 1, 100000, rtt) == -2, "an impossible CPU is refused");
    }
    rc_pingpong_free(p);
    CHECK(rc_pingpong_new(0, -1) == NULL, "msg_size 0 refused");
}

static int connect_to(int port)
{
    struct sockaddr_in addr;
    struct timeval tv;
    int fd = socket(AF_INET, SOCK_STREAM, 0);

    if (fd < 0) {
        return -1;
    }
    memset(&addr, 0, sizeof(addr));
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    addr.sin_port = htons((unsigned short)port);
    tv.tv_sec = 5; /* a missing reply fails the test instead of hanging it */
    tv.tv_usec = 0;
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, (const void *)&tv, sizeof(tv));
    if (connect(fd, (struct sockaddr *)&addr, sizeof(addr)) != 0) {
        close(fd);
        return -1;
    }
    return fd;
}

static size_t read_n(int fd, unsigned char *buf, size_t n)
{
    size_t got = 0;
    while (got < n) {
        ssize_t k = recv(fd, buf + got, n - got, 0);
        if (k <= 0) {
            break;
        }
        got += (size_t)k;
    }
    return got;
}

static void test_responder(void)
{
    /* keys: SYNC0 payload 00 and SYNC1 payload 01; replies: the SYNC echo frames */
    static const unsigned char keys[] = {0x00, 0x01};
    static const size_t key_lens[] = {1, 1};
    static const unsigned char replies[] = {0xFA, 0xFB, 0x03, 0x00, 0x00, 0x00,
                                            0xFA, 0xFB, 0x03, 0x01, 0x00, 0x01};
    static const size_t reply_lens[] = {6, 6};
    static const unsigned char sync0[] = {0xFA, 0xFB, 0x03, 0x00, 0x00, 0x00};
    static const unsigned char sync1[] = {0xFA, 0xFB, 0x03, 0x01, 0x00, 0x01};
    /* ENABLE 1: not in the table, no reply */
    static const unsigned char enable[] = {0xFA, 0xFB, 0x06, 0x04, 0x3B, 0x01, 0x00, 0x05, 0x3B};
    unsigned char buf[16];
    rc_responder_stats st;
    rc_responder *r = rc_responder_new(keys, key_lens, replies, reply_lens, 2);
    int port;
    int fd;

    CHECK(r != NULL, "responder created");
    if (r == NULL) {
        return;
    }
    port = rc_responder_start(r, rc_pin_supported() ? 0 : -1);
    CHECK(port > 0, "responder listens");
    fd = connect_to(port);
    CHECK(fd >= 0, "client connects");
    if (fd >= 0) {
        CHECK(send(fd, enable, sizeof(enable), 0) == (ssize_t)sizeof(enable), "send ENABLE");
        CHECK(send(fd, sync1, 2, 0) == 2, "send half a frame");
        CHECK(send(fd, sync1 + 2, 4, 0) == 4, "send its other half");
        CHECK(read_n(fd, buf, 6) == 6 && memcmp(buf, sync1, 6) == 0, "SYNC1 echoed, only");
        close(fd);
    }
    fd = connect_to(port);
    CHECK(fd >= 0, "a second client connects");
    if (fd >= 0) {
        CHECK(send(fd, sync0, sizeof(sync0), 0) == 6, "send SYNC0");
        CHECK(read_n(fd, buf, 6) == 6 && memcmp(buf, sync0, 6) == 0, "SYNC0 echoed");
        rc_responder_get_stats(r, &st);
        CHECK(st.connections == 2 && st.frames == 3 && st.replies == 2, "counters");
        CHECK(rc_responder_stop(r) == 0, "stops with a client connected");
        CHECK(read_n(fd, buf, 1) == 0, "the client sees the end");
        close(fd);
    }
    CHECK(rc_responder_stop(r) == -1, "second stop is a no-op");
    rc_responder_free(r);
    CHECK(rc_responder_new(keys, reply_lens, replies, reply_lens, 300) == NULL,
          "more than 256 entries refused");
}

int main(void)
{
    test_pingpong_chunks();
    test_responder();
    printf("benchmark peers: %lu passed, %lu failed\n", n_pass, n_fail);
    return n_fail == 0 ? 0 : 1;
}

#endif
