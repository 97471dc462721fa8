/* What the cyclic pump's C files share (cyclic_pump.c: the pump, its thread, the send queue and
 * the receive ring; cyclic_pump_periodic.c: the periodic streams): the pump's state and the
 * helpers both use. Not an interface: cyclic_pump.h is the whole one. Every field of struct pump
 * after `lock` is read and written under it (cyclic_pump.c says why). */
#ifndef COBOT_HMI_CYCLIC_PUMP_INTERNAL_H
#define COBOT_HMI_CYCLIC_PUMP_INTERNAL_H

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>

#include "cyclic_pump.h"

#define NEVER INT64_MAX

typedef struct {
    int64_t due_ns;
    int64_t tag;
    uint32_t ip; /* host order, like every address and port of this interface */
    uint16_t port;
    int32_t len; /* -1: free slot */
} send_slot;

typedef struct {
    int64_t stamp_ns;
    uint32_t ip;
    uint16_t port;
    int32_t len;
} ring_meta;

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
    uint8_t *data;
} periodic;

struct pump {
    int fd;
    int kick_fd;
    int notify_fd;
    pthread_mutex_t life; /* pump_start and pump_stop: thread, thread_started */
    pthread_t thread;
    int thread_started;
    pthread_mutex_t lock; /* everything below */
    atomic_int running;

    int queue_cap;
    int queue_bytes;
    send_slot *queue;
    uint8_t *queue_data;
    int queued;
    periodic periodics[PERIODIC_MAX];

    int ring_cap;
    int ring_bytes;
    ring_meta *ring;
    uint8_t *ring_data;
    int ring_head;
    int ring_count;

    int read_on_readable;
    int64_t notify_interval_ns;
    int64_t silence_ns; /* 0: off */
    int64_t last_rx_ns; /* receive time of the newest datagram, 0 before the first */
    int silence_reported;
    int64_t last_notify_ns;
    int notified;
    int64_t sleeping_until;

    int64_t counters[C_COUNT];
};

/* Wake the pump's thread (it re-reads its schedule). */
void pump_kick(pump *p);
/* Send one datagram now (lock held), counting it and how late it left. */
void pump_send_one(pump *p, const uint8_t *data, int32_t len, uint32_t ip, uint16_t port,
                   int64_t due_ns, int64_t now);
/* The periodic streams' packets due at `now` sent (lock held); the next one's due time. */
void pump_send_periodic_due(pump *p, int64_t now);
int64_t pump_periodic_next_due(pump *p);

#endif
