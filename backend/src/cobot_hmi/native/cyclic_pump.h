/* The cyclic pump's interface (cyclic_pump.c says what it is and why). Every address and port is
 * in host byte order; every time is CLOCK_MONOTONIC in nanoseconds. Each call is safe from any
 * thread at any time between pump_new and pump_free. */
#ifndef COBOT_HMI_CYCLIC_PUMP_H
#define COBOT_HMI_CYCLIC_PUMP_H

#include <stdint.h>

typedef struct pump pump;

/* Periodic streams one pump holds at once: one per class 1 connection on its socket. A PLC
 * holds dozens of adapter connections from one UDP 2222 socket (docs/protocol.md); a slot costs
 * one datagram's buffer, and a wake-up scans only the active ones' due times. */
#define PUMP_PERIODIC_MAX 64

/* What pump_counters reports, in this order. */
enum {
    C_SENT,
    C_SEND_ERRORS,
    C_RECEIVED,
    C_RING_OVERFLOWS,
    C_WAKEUPS,
    C_MAX_LATE_NS,
    C_REALTIME, /* 1 when the thread runs SCHED_FIFO */
    C_COUNT
};

/* A pump for the UDP socket `fd` (which stays the caller's: it must outlive the pump): up to
 * `queue_cap` queued datagrams of at most `queue_bytes`, a ring of `ring_cap` received ones of
 * at most `ring_bytes`. NULL when out of memory or file descriptors. */
pump *pump_new(int fd, int queue_cap, int queue_bytes, int ring_cap, int ring_bytes);
int pump_start(pump *p);  /* 0, or -1 when the thread cannot be created */
void pump_stop(pump *p);  /* stops and joins the thread; nothing if it is not running */
void pump_free(pump *p);  /* pump_stop, then frees everything (NULL: nothing) */
int pump_notify_fd(pump *p);
void pump_configure(pump *p, int read_on_readable, int64_t notify_interval_ns, int64_t silence_ns);
int pump_queue(pump *p, int64_t due_ns, uint32_t ip, uint16_t port, const uint8_t *data, int len,
               int64_t tag);
int pump_cancel(pump *p, int64_t tag, int64_t from_ns, int64_t *first_due_ns);
int pump_queued(pump *p, int64_t tag);
int pump_take(pump *p, int drain_first, uint8_t *buf, int buf_len, int32_t *lens, int64_t *stamps,
              uint32_t *ips, uint16_t *ports, int max);
void pump_counters(pump *p, int64_t *out); /* C_COUNT values */
int pump_periodic_start(pump *p, int64_t tag, int64_t first_due_ns, int64_t period_ns, uint32_t ip,
                        uint16_t port, const uint8_t *data, int len, int off32, uint32_t first32,
                        int off16, uint16_t first16);
int pump_periodic_data(pump *p, int64_t tag, const uint8_t *data, int len);
int pump_periodic_next(pump *p, int64_t tag, int stop, uint32_t *next32, uint16_t *next16,
                       int64_t *next_due_ns);
int64_t pump_now_ns(void);

#endif
