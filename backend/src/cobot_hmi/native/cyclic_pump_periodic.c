/* The cyclic pump's periodic streams (cyclic_pump.c says what the pump is): one datagram sent
 * every period from a template whose two counters (a 32-bit and a 16-bit little-endian field at
 * offsets Python gives) rise by one per packet; Python replaces the template when the data
 * changes (pump_periodic_data), without waking for each packet. The pump's thread sends them
 * (pump_send_periodic_due) at each wake-up, under the pump's lock like every call here. */
#include <string.h>

#include "cyclic_pump_internal.h"

static void put_le(uint8_t *at, uint32_t value, int bytes) {
    for (int b = 0; b < bytes; b++) at[b] = (uint8_t)(value >> (8 * b));
}

void pump_send_periodic_due(pump *p, int64_t now) {
    for (int i = 0; i < PERIODIC_MAX; i++) {
        periodic *s = &p->periodics[i];
        if (!s->active || s->due_ns > now) continue;
        if (s->off32 >= 0) put_le(s->data + s->off32, s->count32, 4);
        if (s->off16 >= 0) put_le(s->data + s->off16, s->count16, 2);
        pump_send_one(p, s->data, s->len, s->ip, s->port, s->due_ns, now);
        s->count32++;
        s->count16++;
        s->due_ns += s->period_ns;
        /* Stalled for more than a period: skip the missed packets (one catch-up, no burst) and
         * stay on the stream's own grid, so streams started on one phase keep sharing it. */
        if (s->due_ns < now - s->period_ns)
            s->due_ns += (now - s->due_ns) / s->period_ns * s->period_ns;
    }
}

int64_t pump_periodic_next_due(pump *p) {
    int64_t next = NEVER;
    for (int i = 0; i < PERIODIC_MAX; i++) {
        if (p->periodics[i].active && p->periodics[i].due_ns < next) next = p->periodics[i].due_ns;
    }
    return next;
}

/* Start (or restart) the periodic stream `tag`: `data` every `period_ns` from `first_due_ns` to
 * `ip`:`port`, with the 32-bit counter at `off32` and the 16-bit one at `off16` (little-endian,
 * -1: none) starting at `first32` and `first16` and rising by one per packet. 0, -1 when every
 * stream is taken, -2 when the datagram is longer than a slot or a counter lies outside it. */
int pump_periodic_start(pump *p, int64_t tag, int64_t first_due_ns, int64_t period_ns, uint32_t ip,
                        uint16_t port, const uint8_t *data, int len, int off32, uint32_t first32,
                        int off16, uint16_t first16) {
    if (len < 0 || len > p->queue_bytes || off32 + 4 > len || off16 + 2 > len || period_ns <= 0)
        return -2;
    pthread_mutex_lock(&p->lock);
    int slot = -1;
    for (int i = 0; i < PERIODIC_MAX; i++) {
        if (p->periodics[i].active && p->periodics[i].tag == tag) { slot = i; break; }
        if (!p->periodics[i].active && slot < 0) slot = i;
    }
    if (slot < 0) {
        pthread_mutex_unlock(&p->lock);
        return -1;
    }
    periodic *s = &p->periodics[slot];
    memcpy(s->data, data, (size_t)len);
    s->len = len;
    s->tag = tag;
    s->due_ns = first_due_ns;
    s->period_ns = period_ns;
    s->ip = ip;
    s->port = port;
    s->off32 = off32;
    s->off16 = off16;
    s->count32 = first32;
    s->count16 = first16;
    s->active = 1;
    int wake = first_due_ns < p->sleeping_until;
    if (wake) p->sleeping_until = first_due_ns;
    pthread_mutex_unlock(&p->lock);
    if (wake) pump_kick(p);
    return 0;
}

/* The periodic stream `tag` sends `data` from its next packet on (its counters go on rising).
 * 0, -1 when there is no such stream, -2 when the datagram does not fit. */
int pump_periodic_data(pump *p, int64_t tag, const uint8_t *data, int len) {
    pthread_mutex_lock(&p->lock);
    for (int i = 0; i < PERIODIC_MAX; i++) {
        periodic *s = &p->periodics[i];
        if (s->active && s->tag == tag) {
            if (len < 0 || len > p->queue_bytes || s->off32 + 4 > len || s->off16 + 2 > len) {
                pthread_mutex_unlock(&p->lock);
                return -2;
            }
            memcpy(s->data, data, (size_t)len);
            s->len = len;
            pthread_mutex_unlock(&p->lock);
            return 0;
        }
    }
    pthread_mutex_unlock(&p->lock);
    return -1;
}

/* The periodic stream `tag`'s next packet: its counters and due time into *next32, *next16 and
 * *next_due_ns; with `stop`, the stream ends (that packet is not sent). 0, or -1 when there is
 * no such stream. */
int pump_periodic_next(pump *p, int64_t tag, int stop, uint32_t *next32, uint16_t *next16,
                       int64_t *next_due_ns) {
    pthread_mutex_lock(&p->lock);
    for (int i = 0; i < PERIODIC_MAX; i++) {
        periodic *s = &p->periodics[i];
        if (s->active && s->tag == tag) {
            if (stop) s->active = 0;
            *next32 = s->count32;
            *next16 = s->count16;
            *next_due_ns = s->due_ns;
            pthread_mutex_unlock(&p->lock);
            return 0;
        }
    }
    pthread_mutex_unlock(&p->lock);
    return -1;
}
