/*
 * One writer, many readers ring of timestamped fixed-size records.
 *
 * Pushing touches no reader: each reader's overflow is computed lazily from the
 * global push counter when it is queried or read. Only counter differences are used,
 * so a wrap of unsigned long is harmless.
 *
 * Thread-safe on its own: every call that touches the cursors or the data takes the
 * ring's mutex (a POSIX mutex, a critical section on Windows) for the C work only.
 * Callers (the cffi wrapper releases the GIL around each call) need no lock of their
 * own, so no caller-level lock is ever held while a thread waits to retake the GIL.
 * Elsewhere (no POSIX threads, no Windows) the caller must serialise calls.
 */
#if !defined(_WIN32) && !defined(_POSIX_C_SOURCE)
#define _POSIX_C_SOURCE 200112L
#endif

#include <stdlib.h>
#include <string.h>

#include "robocli_core.h"

#if defined(_WIN32)
#include <windows.h>
typedef CRITICAL_SECTION rc_mutex;
static int mutex_init(rc_mutex *m)
{
    InitializeCriticalSection(m);
    return 0;
}
#define mutex_destroy(m) DeleteCriticalSection(m)
#define mutex_lock(m) EnterCriticalSection(m)
#define mutex_unlock(m) LeaveCriticalSection(m)
#elif defined(__unix__) || defined(__APPLE__)
#include <pthread.h>
typedef pthread_mutex_t rc_mutex;
#define mutex_init(m) pthread_mutex_init((m), NULL)
#define mutex_destroy(m) pthread_mutex_destroy(m)
#define mutex_lock(m) pthread_mutex_lock(m)
#define mutex_unlock(m) pthread_mutex_unlock(m)
#else
typedef int rc_mutex; /* no threads known here: the caller serialises */
#define mutex_init(m) ((void)(m), 0)
#define mutex_destroy(m) ((void)(m))
#define mutex_lock(m) ((void)(m))
#define mutex_unlock(m) ((void)(m))
#endif

/* The mutex of a ring the API passes as const (its cursors still move). */
#define RING_MUTEX(r) (&((rc_ring *)(r))->mu)

typedef struct rc_reader {
    int used;
    size_t limit;
    unsigned long cursor; /* value of `head` at this reader's next unread record */
    unsigned long lost;
} rc_reader;

struct rc_ring {
    size_t record_size;
    size_t capacity;
    unsigned char *data;
    double *times;
    size_t wpos;        /* slot of the next push */
    unsigned long head; /* records pushed since creation */
    rc_reader *readers;
    int nreaders;       /* slots allocated in readers */
    rc_mutex mu;        /* guards everything above except the immutable sizes */
};

rc_ring *rc_ring_new(size_t record_size, size_t capacity)
{
    rc_ring *r;

    if (record_size == 0 || capacity == 0 || capacity > ((size_t)-1) / record_size ||
        capacity > ((size_t)-1) / sizeof(double)) {
        return NULL;
    }
    r = (rc_ring *)malloc(sizeof(*r));
    if (r == NULL) {
        return NULL;
    }
    r->record_size = record_size;
    r->capacity = capacity;
    r->data = (unsigned char *)malloc(record_size * capacity);
    r->times = (double *)malloc(sizeof(double) * capacity);
    if (r->data == NULL || r->times == NULL || mutex_init(&r->mu) != 0) {
        free(r->data);
        free(r->times);
        free(r);
        return NULL;
    }
    r->wpos = 0;
    r->head = 0;
    r->readers = NULL;
    r->nreaders = 0;
    return r;
}

void rc_ring_free(rc_ring *r)
{
    if (r != NULL) {
        mutex_destroy(&r->mu);
        free(r->data);
        free(r->times);
        free(r->readers);
        free(r);
    }
}

size_t rc_ring_record_size(const rc_ring *r)
{
    return r->record_size;
}

size_t rc_ring_capacity(const rc_ring *r)
{
    return r->capacity;
}

unsigned long rc_ring_pushed(const rc_ring *r)
{
    unsigned long head;
    mutex_lock(RING_MUTEX(r));
    head = r->head;
    mutex_unlock(RING_MUTEX(r));
    return head;
}

void rc_ring_push(rc_ring *r, double t, const void *record)
{
    size_t w;
    mutex_lock(&r->mu);
    w = r->wpos;
    memcpy(r->data + w * r->record_size, record, r->record_size);
    r->times[w] = t;
    w++;
    r->wpos = w == r->capacity ? 0 : w;
    r->head++;
    mutex_unlock(&r->mu);
}

void rc_ring_push_many(rc_ring *r, const double *t, const void *records, size_t n)
{
    const unsigned char *src = (const unsigned char *)records;
    size_t rs = r->record_size;
    size_t cap = r->capacity;

    mutex_lock(&r->mu);
    r->head += (unsigned long)n;
    if (n > cap) {
        /* only the last `cap` records survive; skip the others */
        size_t skip = n - cap;
        r->wpos = (r->wpos + skip % cap) % cap;
        src += skip * rs;
        t += skip;
        n = cap;
    }
    while (n > 0) {
        size_t k = cap - r->wpos;
        if (k > n) {
            k = n;
        }
        memcpy(r->data + r->wpos * rs, src, k * rs);
        memcpy(r->times + r->wpos, t, k * sizeof(double));
        src += k * rs;
        t += k;
        n -= k;
        r->wpos += k;
        if (r->wpos == cap) {
            r->wpos = 0;
        }
    }
    mutex_unlock(&r->mu);
}

static rc_reader *get_reader(const rc_ring *r, int reader)
{
    if (reader < 0 || reader >= r->nreaders || !r->readers[reader].used) {
        return NULL;
    }
    return &r->readers[reader];
}

/* Apply the reader's limit: drop (and count) what overflowed since last time. */
static void settle(const rc_ring *r, rc_reader *rd)
{
    unsigned long unread = r->head - rd->cursor;
    if (unread > (unsigned long)rd->limit) {
        unsigned long over = unread - (unsigned long)rd->limit;
        rd->lost += over;
        rd->cursor += over;
    }
}

/* The bodies below run with the ring's mutex held (see the wrappers at the end). */

static int add_reader(rc_ring *r, size_t limit)
{
    int i;
    rc_reader *rd;

    for (i = 0; i < r->nreaders; i++) {
        if (!r->readers[i].used) {
            break;
        }
    }
    if (i == r->nreaders) {
        int n = r->nreaders == 0 ? 4 : r->nreaders * 2;
        rc_reader *nr;
        int k;
        if (r->nreaders > 1000000) {
            return -1;
        }
        nr = (rc_reader *)realloc(r->readers, sizeof(rc_reader) * (size_t)n);
        if (nr == NULL) {
            return -1;
        }
        for (k = r->nreaders; k < n; k++) {
            nr[k].used = 0;
        }
        r->readers = nr;
        r->nreaders = n;
    }
    rd = &r->readers[i];
    rd->used = 1;
    rd->limit = (limit == 0 || limit > r->capacity) ? r->capacity : limit;
    rd->cursor = r->head;
    rd->lost = 0;
    return i;
}

static size_t available(const rc_ring *r, int reader)
{
    rc_reader *rd = get_reader(r, reader);
    unsigned long unread;
    if (rd == NULL) {
        return 0;
    }
    unread = r->head - rd->cursor;
    return unread > (unsigned long)rd->limit ? rd->limit : (size_t)unread;
}

static unsigned long lost(const rc_ring *r, int reader)
{
    rc_reader *rd = get_reader(r, reader);
    unsigned long unread;
    if (rd == NULL) {
        return 0;
    }
    unread = r->head - rd->cursor;
    if (unread > (unsigned long)rd->limit) {
        return rd->lost + (unread - (unsigned long)rd->limit);
    }
    return rd->lost;
}

static size_t read_records(rc_ring *r, int reader, double *t_out, void *rec_out, size_t max)
{
    rc_reader *rd = get_reader(r, reader);
    unsigned char *dst = (unsigned char *)rec_out;
    size_t rs = r->record_size;
    size_t cap = r->capacity;
    size_t count;
    size_t pos;
    size_t left;

    if (rd == NULL) {
        return 0;
    }
    settle(r, rd);
    count = (size_t)(r->head - rd->cursor); /* <= limit <= capacity */
    if (count > max) {
        count = max;
    }
    /* slot of the oldest unread record */
    pos = (r->wpos + cap - (size_t)(r->head - rd->cursor)) % cap;
    left = count;
    while (left > 0) {
        size_t k = cap - pos;
        if (k > left) {
            k = left;
        }
        if (t_out != NULL) {
            memcpy(t_out, r->times + pos, k * sizeof(double));
            t_out += k;
        }
        if (dst != NULL) {
            memcpy(dst, r->data + pos * rs, k * rs);
            dst += k * rs;
        }
        left -= k;
        pos += k;
        if (pos == cap) {
            pos = 0;
        }
    }
    rd->cursor += (unsigned long)count;
    return count;
}

/* ------------------------------------------------------------------ locked API */

int rc_ring_add_reader(rc_ring *r, size_t limit)
{
    int id;
    mutex_lock(&r->mu);
    id = add_reader(r, limit);
    mutex_unlock(&r->mu);
    return id;
}

void rc_ring_remove_reader(rc_ring *r, int reader)
{
    rc_reader *rd;
    mutex_lock(&r->mu);
    rd = get_reader(r, reader);
    if (rd != NULL) {
        rd->used = 0;
    }
    mutex_unlock(&r->mu);
}

size_t rc_ring_available(const rc_ring *r, int reader)
{
    size_t n;
    mutex_lock(RING_MUTEX(r));
    n = available(r, reader);
    mutex_unlock(RING_MUTEX(r));
    return n;
}

unsigned long rc_ring_lost(const rc_ring *r, int reader)
{
    unsigned long n;
    mutex_lock(RING_MUTEX(r));
    n = lost(r, reader);
    mutex_unlock(RING_MUTEX(r));
    return n;
}

size_t rc_ring_read(rc_ring *r, int reader, double *t_out, void *rec_out, size_t max)
{
    size_t n;
    mutex_lock(&r->mu);
    n = read_records(r, reader, t_out, rec_out, max);
    mutex_unlock(&r->mu);
    return n;
}
