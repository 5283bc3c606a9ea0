/*
 * Timestamp alignment of one sorted stream onto a sorted reference timeline, O(n + m).
 *
 * The stream cursor advances through a branch-free window of 4 comparisons (exact for
 * sorted input), and the nearest choice uses conditional moves, so that randomly spaced
 * timestamps do not cost a branch misprediction per reference point. Unsorted input (or
 * NaN) gives meaningless but memory-safe results.
 */
#include "robocli_core.h"

/* Number of samples ts[0..n) that are <= x, starting from a known count k. */
static size_t advance(const double *ts, size_t n, size_t k, double x)
{
    while (k + 4 <= n) {
        size_t c = (size_t)(ts[k] <= x) + (size_t)(ts[k + 1] <= x) + (size_t)(ts[k + 2] <= x) +
                   (size_t)(ts[k + 3] <= x);
        k += c;
        if (c < 4) {
            return k;
        }
    }
    while (k < n && ts[k] <= x) {
        k++;
    }
    return k;
}

void rc_align_nearest(const double *ts, size_t n, const double *ref, size_t m, double tol,
                      long *out_idx)
{
    size_t k = 0;             /* number of samples with ts <= ref[i] */
    size_t cached_j = (size_t)-1;
    size_t cached_run = 0;    /* first index of the run of samples equal to ts[cached_j] */
    size_t i;

    for (i = 0; i < m; i++) {
        double x = ref[i];
        long best;

        k = advance(ts, n, k, x);
        if (k == 0) {
            best = (n > 0 && ts[0] - x <= tol) ? 0 : -1;
        } else {
            size_t j = k - 1;
            size_t left = j;
            double d0 = x - ts[j];
            double d;
            size_t cand;

            if (j > 0 && ts[j - 1] == ts[j]) {
                /* duplicates: ties go to the earliest equal sample */
                if (j != cached_j) {
                    size_t r = j;
                    while (r > 0 && ts[r - 1] == ts[j]) {
                        r--;
                    }
                    cached_j = j;
                    cached_run = r;
                }
                left = cached_run;
            }
            if (k < n) {
                double d1 = ts[k] - x;
                int right = d1 < d0;
                d = right ? d1 : d0;
                cand = right ? k : left;
            } else {
                d = d0;
                cand = left;
            }
            best = d <= tol ? (long)cand : -1L;
        }
        out_idx[i] = best;
    }
}

void rc_align_linear(const double *ts, size_t n, const double *ref, size_t m, long *out_idx,
                     double *out_w)
{
    size_t k = 0; /* number of samples with ts <= ref[i] */
    size_t i;

    for (i = 0; i < m; i++) {
        double x = ref[i];

        k = advance(ts, n, k, x);
        if (k == 0 || x > ts[n - 1]) {
            out_idx[i] = -1;
            out_w[i] = 0.0;
        } else if (k == n) {
            /* x == ts[n-1] */
            if (n == 1) {
                out_idx[i] = 0;
                out_w[i] = 0.0;
            } else {
                out_idx[i] = (long)(n - 2);
                out_w[i] = 1.0;
            }
        } else {
            double t0 = ts[k - 1];
            out_idx[i] = (long)(k - 1);
            out_w[i] = (x - t0) / (ts[k] - t0);
        }
    }
}
