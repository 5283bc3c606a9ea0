/*
 * The C test programs' one assertion (test_core.c, test_bench.c): CHECK(cond, what) counts a
 * pass, or a failure printed with its place and condition; each program ends with
 * "N passed, M failed" from n_pass and n_fail. Included once per test program.
 */
#ifndef ROBOCLI_CHECK_H
#define ROBOCLI_CHECK_H

#include <stdio.h>

static unsigned long n_pass = 0;
static unsigned long n_fail = 0;

#define CHECK(cond, what)                                                                  \
    do {                                                                                   \
        if (cond) {                                                                        \
            n_pass++;                                                                      \
        } else {                                                                           \
            n_fail++;                                                                      \
            fprintf(stderr, "FAIL %s:%d: %s [%s]\n", __FILE__, __LINE__, (what), #cond);   \
        }                                                                                  \
    } while (0)

#endif
