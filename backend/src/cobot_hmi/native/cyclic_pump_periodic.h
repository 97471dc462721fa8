/* The cyclic pump's periodic streams, as data (cyclic_pump_periodic.c): one datagram every period
 * from a template whose two counters (a 32-bit and a 16-bit little-endian field at offsets Python
 * gives) rise by one per packet. The table knows no pump, socket, lock or thread: cyclic_pump.c
 * holds one in its state, calls these under its lock and sends what they say is due, so the pump
 * uses this file and this file uses nothing of the pump. */
#ifndef COBOT_HMI_CYCLIC_PUMP_PERIODIC_H
#define COBOT_HMI_CYCLIC_PUMP_PERIODIC_H

#include <stdint.h>

#include "cyclic_pump.h"

#define PERIODIC_MAX PUMP_PERIODIC_MAX

typedef struct {
    int active;
    int64_t tag;
    int64_t due_ns;
    int64_t period_ns;
    uint32_t ip;
    uint16_t port;
    int32_t len;
    int32_t off32; /* -1: no such counter */
    int32_t off16;
    uint32_t count32; /* the values of the next packet */
    uint16_t count16;
    uint8_t *data; /* a template of up to the pump's datagram size */
} periodic;

/* Whether `len` bytes with counters at `off32` and `off16` fit a template of `max_len` bytes. */
int periodic_fits(int len, int max_len, int off32, int off16);
/* The active stream `tag`, or NULL. */
periodic *periodic_find(periodic *streams, int64_t tag);
/* The slot for stream `tag`: its own if active, else the first free one; NULL when all are taken. */
periodic *periodic_slot(periodic *streams, int64_t tag);
/* (Re)start `s` as stream `tag` (the arguments of pump_periodic_start, already checked). */
void periodic_set(periodic *s, int64_t tag, int64_t first_due_ns, int64_t period_ns, uint32_t ip,
                  uint16_t port, const uint8_t *data, int len, int off32, uint32_t first32,
                  int off16, uint16_t first16);
/* The next stream from index *from on that is due at `now`, its counters written into its
 * template (*from moves past it); NULL when none is. Send it, then periodic_advance it. */
periodic *periodic_next_due_packet(periodic *streams, int64_t now, int *from);
/* `s`'s packet went out: its counters rise and its due time moves a period on (a stream that
 * stalled for more than a period skips the missed packets and stays on its own grid). */
void periodic_advance(periodic *s, int64_t now);
/* The earliest due time of the active streams (INT64_MAX: none). */
int64_t periodic_next_due(const periodic *streams);

#endif
