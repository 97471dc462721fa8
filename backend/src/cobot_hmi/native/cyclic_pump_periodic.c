/* The cyclic pump's periodic streams as data (cyclic_pump_periodic.h says what they are and who
 * calls these, always under the pump's lock). Nothing here sends, sleeps or locks. */
#include "cyclic_pump_periodic.h"

#include <string.h>

static void put_le(uint8_t *at, uint32_t value, int bytes) {
    for (int b = 0; b < bytes; b++) at[b] = (uint8_t)(value >> (8 * b));
}

int periodic_fits(int len, int max_len, int off32, int off16) {
    return len >= 0 && len <= max_len && off32 + 4 <= len && off16 + 2 <= len;
}

periodic *periodic_find(periodic *streams, int64_t tag) {
    for (int i = 0; i < PERIODIC_MAX; i++) {
        if (streams[i].active && streams[i].tag == tag) return &streams[i];
    }
    return NULL;
}

periodic *periodic_slot(periodic *streams, int64_t tag) {
    periodic *own = periodic_find(streams, tag);
    if (own) return own;
    for (int i = 0; i < PERIODIC_MAX; i++) {
        if (!streams[i].active) return &streams[i];
    }
    return NULL;
}

void periodic_set(periodic *s, int64_t tag, int64_t first_due_ns, int64_t period_ns, uint32_t ip,
                  uint16_t port, const uint8_t *data, int len, int off32, uint32_t first32,
                  int off16, uint16_t first16) {
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
}

periodic *periodic_next_due_packet(periodic *streams, int64_t now, int *from) {
    for (; *from < PERIODIC_MAX; (*from)++) {
        periodic *s = &streams[*from];
        if (!s->active || s->due_ns > now) continue;
        if (s->off32 >= 0) put_le(s->data + s->off32, s->count32, 4);
        if (s->off16 >= 0) put_le(s->data + s->off16, s->count16, 2);
        (*from)++;
        return s;
    }
    return NULL;
}

void periodic_advance(periodic *s, int64_t now) {
    s->count32++;
    s->count16++;
    s->due_ns += s->period_ns;
    /* Stalled for more than a period: skip the missed packets (one catch-up, no burst) and stay
     * on the stream's own grid, so streams started on one phase keep sharing it. */
    if (s->due_ns < now - s->period_ns)
        s->due_ns += (now - s->due_ns) / s->period_ns * s->period_ns;
}

int64_t periodic_next_due(const periodic *streams) {
    int64_t next = INT64_MAX;
    for (int i = 0; i < PERIODIC_MAX; i++) {
        if (streams[i].active && streams[i].due_ns < next) next = streams[i].due_ns;
    }
    return next;
}
