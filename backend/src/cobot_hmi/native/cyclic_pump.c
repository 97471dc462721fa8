/* The cyclic pump: the one part of the class 1 path that runs outside the Python interpreter.
 *
 * A class 1 endpoint must put a datagram on the wire every RPI (2 ms in bench/cyclic). Waking a
 * Python thread for each one costs ~60-100 us of CPU on a shared VM (the interpreter's working
 * set is cold after every sleep), far more than the packet itself. So the protocol stays in
 * Python (cobot_hmi.enip builds every byte, cobot_hmi.udp_endpoint owns the socket) and this
 * thread only does the timing:
 *
 *   - send queue: datagrams Python built ahead of time, each with the CLOCK_MONOTONIC instant
 *     it is due; the thread sleeps until the earliest one (1 us timer slack) and sends it.
 *     Python can take back what has not left yet (pump_cancel) when the data changes.
 *   - periodic streams (a table of them, cyclic_pump_periodic.c, which knows nothing of the
 *     pump): one datagram sent every period from a template whose two counters (a 32-bit and a
 *     16-bit little-endian field at offsets Python gives) rise by one per packet; Python
 *     replaces the template when the data changes (pump_periodic_data), without waking for
 *     each packet.
 *   - receive ring: at every wake-up the thread reads every datagram waiting in the socket,
 *     with the kernel's receive time (SO_TIMESTAMPNS, turned into CLOCK_MONOTONIC), into a ring
 *     Python empties with pump_take. Nothing is lost by reading late: the receive time travels
 *     with the datagram.
 *   - notification: an eventfd Python's event loop watches, written when the ring holds data and
 *     at least `notify_interval` has passed since the last notification, so Python wakes once
 *     per batch of packets instead of once per packet (0: at once); and once when no datagram
 *     has come for `silence` (a watchdog's cue: Python then looks at once, not at its next
 *     batch).
 *
 * It knows nothing of EtherNet/IP, nor of Python: cyclic_pump.h is the whole interface, which
 * _cyclic_pump_module.c wraps as the extension module cobot_hmi.native._cyclic_pump and
 * backend/tests/native/tsan_harness.c drives under ThreadSanitizer.
 *
 * Thread safety, by construction: every field the thread and the callers share is read and
 * written under `lock` (each call holds it for microseconds only), except `running`, a C11
 * atomic, and the fields fixed at pump_new (sizes, buffers' addresses, file descriptors).
 * Starting and stopping the thread take `life`, a second lock, so that two concurrent
 * pump_stop calls join it once; `lock` is never held while joining.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "cyclic_pump_periodic.h"

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

/* The pump's state. Every field after `lock` is read and written under it. */
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

/* Real-time priority of the thread when the system allows it (as a PLC runtime's I/O task):
 * low among real-time priorities, and the thread sleeps between packets, so it only ever
 * preempts ordinary work for the microseconds a packet takes. */
#define PUMP_FIFO_PRIORITY 10

static int64_t clock_ns(clockid_t clock) {
    struct timespec t;
    clock_gettime(clock, &t);
    return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

static int64_t mono_ns(void) { return clock_ns(CLOCK_MONOTONIC); }

int64_t pump_now_ns(void) { return mono_ns(); }

pump *pump_new(int fd, int queue_cap, int queue_bytes, int ring_cap, int ring_bytes) {
    pump *p = calloc(1, sizeof *p);
    if (!p) return NULL;
    p->fd = fd;
    p->queue_cap = queue_cap;
    p->queue_bytes = queue_bytes;
    p->ring_cap = ring_cap;
    p->ring_bytes = ring_bytes;
    p->queue = calloc((size_t)queue_cap, sizeof *p->queue);
    p->queue_data = malloc((size_t)queue_cap * (size_t)queue_bytes);
    p->ring = calloc((size_t)ring_cap, sizeof *p->ring);
    p->ring_data = malloc((size_t)ring_cap * (size_t)ring_bytes);
    p->kick_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    p->notify_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    p->last_notify_ns = -NEVER;
    p->sleeping_until = NEVER;
    if (!p->queue || !p->queue_data || !p->ring || !p->ring_data || p->kick_fd < 0 ||
        p->notify_fd < 0) {
        if (p->kick_fd >= 0) close(p->kick_fd);
        if (p->notify_fd >= 0) close(p->notify_fd);
        free(p->queue); free(p->queue_data); free(p->ring); free(p->ring_data); free(p);
        return NULL;
    }
    for (int i = 0; i < queue_cap; i++) p->queue[i].len = -1;
    for (int i = 0; i < PERIODIC_MAX; i++) {
        p->periodics[i].data = malloc((size_t)queue_bytes);
        if (!p->periodics[i].data) {
            for (int j = 0; j < i; j++) free(p->periodics[j].data);
            close(p->kick_fd); close(p->notify_fd);
            free(p->queue); free(p->queue_data); free(p->ring); free(p->ring_data); free(p);
            return NULL;
        }
    }
    /* Priority inheritance: a caller preempted while it holds the lock (an ordinary thread on a
     * busy machine) runs at the pump thread's real-time priority until it lets go, instead of
     * holding the pump off for as long as the scheduler keeps it aside. */
    pthread_mutexattr_t inherit;
    pthread_mutexattr_init(&inherit);
    pthread_mutexattr_setprotocol(&inherit, PTHREAD_PRIO_INHERIT);
    pthread_mutex_init(&p->lock, &inherit);
    pthread_mutexattr_destroy(&inherit);
    pthread_mutex_init(&p->life, NULL);
    atomic_init(&p->running, 0);
    return p;
}

int pump_notify_fd(pump *p) { return p->notify_fd; }

/* Wake the pump's thread (it re-reads its schedule). */
static void pump_kick(pump *p) {
    uint64_t one = 1;
    ssize_t ignored = write(p->kick_fd, &one, sizeof one);
    (void)ignored;
}

/* Read every datagram waiting in the socket into the ring (lock held). A full ring drops the
 * oldest datagram: the newest data is what a cyclic consumer wants. */
static void drain_socket(pump *p) {
    int64_t mono_minus_real = mono_ns() - clock_ns(CLOCK_REALTIME);
    for (int n = 0; n < 1024; n++) {
        /* The next slot; in a full ring that is the oldest one's, given up only once a
         * datagram has really come (recvmsg leaves the buffer alone when nothing has). */
        int full = p->ring_count == p->ring_cap;
        int slot = (p->ring_head + p->ring_count) % p->ring_cap;
        struct sockaddr_in from;
        struct iovec iov = {p->ring_data + (size_t)slot * (size_t)p->ring_bytes, (size_t)p->ring_bytes};
        union { struct cmsghdr align; char buf[CMSG_SPACE(sizeof(struct timespec))]; } control;
        struct msghdr msg = {0};
        msg.msg_name = &from;
        msg.msg_namelen = sizeof from;
        msg.msg_iov = &iov;
        msg.msg_iovlen = 1;
        msg.msg_control = control.buf;
        msg.msg_controllen = sizeof control.buf;
        ssize_t got = recvmsg(p->fd, &msg, MSG_DONTWAIT);
        if (got < 0) {
            if (errno == EAGAIN || errno == EWOULDBLOCK) return;
            if (errno == EINTR) continue;
            if (errno == EBADF || errno == ENOTSOCK) return;
            continue; /* an ICMP error reported on the socket: not a datagram */
        }
        int64_t stamp = -1;
        for (struct cmsghdr *c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c)) {
            if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
                struct timespec ts;
                memcpy(&ts, CMSG_DATA(c), sizeof ts);
                stamp = (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec + mono_minus_real;
            }
        }
        if (stamp < 0) stamp = mono_ns();
        /* Receive times never go backwards: the kernel's stamps are wall-clock times moved onto
         * the monotonic clock by an offset read from two clocks one after the other, and a
         * thread preempted between the reads shifts one drain's offset by microseconds. */
        if (stamp < p->last_rx_ns) stamp = p->last_rx_ns;
        ring_meta *m = &p->ring[slot];
        m->stamp_ns = stamp;
        p->last_rx_ns = stamp;
        p->silence_reported = 0;
        m->ip = ntohl(from.sin_addr.s_addr);
        m->port = ntohs(from.sin_port);
        /* A datagram longer than the slot arrives cut to it (MSG_TRUNC): report it one byte too
         * long, so the owner sees it as oversized rather than as a shorter valid packet. */
        m->len = (msg.msg_flags & MSG_TRUNC) ? p->ring_bytes : (int32_t)got;
        if (full) {
            p->ring_head = (p->ring_head + 1) % p->ring_cap;
            p->counters[C_RING_OVERFLOWS]++;
        } else {
            p->ring_count++;
        }
        p->counters[C_RECEIVED]++;
    }
}

static int earliest(pump *p) {
    int best = -1;
    for (int i = 0; i < p->queue_cap; i++) {
        if (p->queue[i].len >= 0 && (best < 0 || p->queue[i].due_ns < p->queue[best].due_ns))
            best = i;
    }
    return best;
}

/* Send one datagram now (lock held), counting it and how late it left. */
static void pump_send_one(pump *p, const uint8_t *data, int32_t len, uint32_t ip, uint16_t port,
                          int64_t due_ns, int64_t now) {
    struct sockaddr_in to = {0};
    to.sin_family = AF_INET;
    to.sin_addr.s_addr = htonl(ip);
    to.sin_port = htons(port);
    ssize_t sent = sendto(p->fd, data, (size_t)len, MSG_DONTWAIT, (struct sockaddr *)&to, sizeof to);
    if (sent < 0) {
        p->counters[C_SEND_ERRORS]++;
    } else {
        p->counters[C_SENT]++;
        int64_t late = now - due_ns;
        if (late > p->counters[C_MAX_LATE_NS]) p->counters[C_MAX_LATE_NS] = late;
    }
}

/* Send what is due; return when the next send is due (NEVER: nothing left). */
static int64_t send_due(pump *p, int64_t now) {
    int from = 0;
    for (periodic *s; (s = periodic_next_due_packet(p->periodics, now, &from));) {
        pump_send_one(p, s->data, s->len, s->ip, s->port, s->due_ns, now);
        periodic_advance(s, now);
    }
    int64_t next = periodic_next_due(p->periodics);
    for (;;) {
        int i = earliest(p);
        if (i < 0) return next;
        if (p->queue[i].due_ns > now) return p->queue[i].due_ns < next ? p->queue[i].due_ns : next;
        send_slot *s = &p->queue[i];
        pump_send_one(p, p->queue_data + (size_t)i * (size_t)p->queue_bytes, s->len, s->ip,
                      s->port, s->due_ns, now);
        s->len = -1;
        p->queued--;
    }
}

static void *run(void *arg) {
    pump *p = arg;
    prctl(PR_SET_TIMERSLACK, 1000UL, 0, 0, 0); /* wake within 1 us, not Linux's 50 us */
    struct sched_param priority = {.sched_priority = PUMP_FIFO_PRIORITY};
    /* Best effort: without the right (CAP_SYS_NICE, RLIMIT_RTPRIO) it stays an ordinary one. */
    int realtime = pthread_setschedparam(pthread_self(), SCHED_FIFO, &priority) == 0;
    pthread_mutex_lock(&p->lock);
    p->counters[C_REALTIME] = realtime;
    pthread_mutex_unlock(&p->lock);
    int woke = 0;
    while (atomic_load(&p->running)) {
        pthread_mutex_lock(&p->lock);
        p->counters[C_WAKEUPS] += woke;
        woke = 1;
        int64_t now = mono_ns();
        int64_t next = send_due(p, now);
        drain_socket(p);
        int sending = next != NEVER;
        if (p->ring_count > 0 && !p->notified && p->notify_interval_ns >= 0) {
            int64_t notify_at = p->last_notify_ns + p->notify_interval_ns;
            if (notify_at <= now) {
                uint64_t one = 1;
                ssize_t ignored = write(p->notify_fd, &one, sizeof one);
                (void)ignored;
                p->notified = 1;
                p->last_notify_ns = now;
            } else if (next == NEVER || next - notify_at > p->notify_interval_ns) {
                next = notify_at; /* else the next send's wake-up notifies, one wake-up less */
            }
        }
        if (p->silence_ns > 0 && p->last_rx_ns > 0 && !p->silence_reported) {
            int64_t quiet_until = p->last_rx_ns + p->silence_ns;
            if (quiet_until <= now) {
                uint64_t one = 1;
                ssize_t ignored = write(p->notify_fd, &one, sizeof one);
                (void)ignored;
                p->notified = 1;
                p->silence_reported = 1;
            } else if (quiet_until < next) {
                next = quiet_until;
            }
        }
        p->sleeping_until = next;
        /* With nothing to send there are no send wake-ups to read at: read as datagrams come. */
        int watch_socket = p->read_on_readable || !sending;
        pthread_mutex_unlock(&p->lock);

        struct pollfd fds[2] = {{p->kick_fd, POLLIN, 0}, {p->fd, POLLIN, 0}};
        struct timespec timeout, *timeout_p = NULL;
        if (next != NEVER) {
            int64_t wait = next - mono_ns();
            if (wait < 0) wait = 0;
            timeout.tv_sec = wait / 1000000000;
            timeout.tv_nsec = wait % 1000000000;
            timeout_p = &timeout;
        }
        int ready = ppoll(fds, watch_socket ? 2 : 1, timeout_p, NULL);
        if (ready > 0 && (fds[0].revents & POLLIN)) {
            uint64_t value;
            ssize_t ignored = read(p->kick_fd, &value, sizeof value);
            (void)ignored;
        }
    }
    return NULL;
}

int pump_start(pump *p) {
    int result = 0;
    pthread_mutex_lock(&p->life);
    if (!p->thread_started) {
        atomic_store(&p->running, 1);
        if (pthread_create(&p->thread, NULL, run, p) == 0) {
            p->thread_started = 1;
            /* Named before pump_start returns: ps and /proc/<pid>/task/<tid>/comm show it. */
            pthread_setname_np(p->thread, "cyclic-pump");
        } else {
            atomic_store(&p->running, 0);
            result = -1;
        }
    }
    pthread_mutex_unlock(&p->life);
    return result;
}

void pump_stop(pump *p) {
    pthread_mutex_lock(&p->life);
    if (p->thread_started) {
        atomic_store(&p->running, 0);
        pump_kick(p);
        pthread_join(p->thread, NULL);
        p->thread_started = 0;
    }
    pthread_mutex_unlock(&p->life);
}

void pump_free(pump *p) {
    if (!p) return;
    pump_stop(p);
    pthread_mutex_destroy(&p->lock);
    pthread_mutex_destroy(&p->life);
    close(p->kick_fd);
    close(p->notify_fd);
    for (int i = 0; i < PERIODIC_MAX; i++) free(p->periodics[i].data);
    free(p->queue); free(p->queue_data); free(p->ring); free(p->ring_data); free(p);
}

/* Read the socket only at the thread's send wake-ups (0: one wake-up per cycle; as datagrams
 * arrive while nothing is queued) or also whenever a datagram arrives (1); notify Python at most
 * every `notify_interval_ns` (negative: never), and once after `silence_ns` without a datagram
 * (0: never). */
void pump_configure(pump *p, int read_on_readable, int64_t notify_interval_ns, int64_t silence_ns) {
    pthread_mutex_lock(&p->lock);
    p->read_on_readable = read_on_readable;
    p->notify_interval_ns = notify_interval_ns;
    p->silence_ns = silence_ns;
    pthread_mutex_unlock(&p->lock);
    pump_kick(p);
}

/* Queue `len` bytes for `ip`:`port` at `due_ns`. 0, or -1 when the queue is
 * full, -2 when the datagram is longer than a slot. */
int pump_queue(pump *p, int64_t due_ns, uint32_t ip, uint16_t port, const uint8_t *data, int len,
               int64_t tag) {
    if (len < 0 || len > p->queue_bytes) return -2;
    pthread_mutex_lock(&p->lock);
    int free_slot = -1;
    for (int i = 0; i < p->queue_cap; i++) {
        if (p->queue[i].len < 0) { free_slot = i; break; }
    }
    if (free_slot < 0) {
        pthread_mutex_unlock(&p->lock);
        return -1;
    }
    send_slot *s = &p->queue[free_slot];
    memcpy(p->queue_data + (size_t)free_slot * (size_t)p->queue_bytes, data, (size_t)len);
    s->due_ns = due_ns;
    s->tag = tag;
    s->ip = ip;
    s->port = port;
    s->len = len;
    p->queued++;
    int wake = due_ns < p->sleeping_until;
    if (wake) p->sleeping_until = due_ns;
    pthread_mutex_unlock(&p->lock);
    if (wake) pump_kick(p);
    return 0;
}

/* Take back every queued datagram of `tag` due at or after `from_ns` (tag -1: every tag);
 * returns how many, and the earliest one's due time in *first_due_ns (unchanged if none). */
int pump_cancel(pump *p, int64_t tag, int64_t from_ns, int64_t *first_due_ns) {
    int removed = 0;
    pthread_mutex_lock(&p->lock);
    for (int i = 0; i < p->queue_cap; i++) {
        send_slot *s = &p->queue[i];
        if (s->len >= 0 && (tag < 0 || s->tag == tag) && s->due_ns >= from_ns) {
            if (removed == 0 || s->due_ns < *first_due_ns) *first_due_ns = s->due_ns;
            s->len = -1;
            p->queued--;
            removed++;
        }
    }
    pthread_mutex_unlock(&p->lock);
    return removed;
}

/* How many datagrams of `tag` wait in the queue. */
int pump_queued(pump *p, int64_t tag) {
    int n = 0;
    pthread_mutex_lock(&p->lock);
    for (int i = 0; i < p->queue_cap; i++) {
        if (p->queue[i].len >= 0 && p->queue[i].tag == tag) n++;
    }
    pthread_mutex_unlock(&p->lock);
    return n;
}

/* Move up to `max` received datagrams out of the ring: their bytes back to back into `buf`
 * (`buf_len` bytes), with length, receive time (CLOCK_MONOTONIC ns), source address and port. With `drain_first`, read the socket first (what arrived since the thread's
 * last wake-up). Clears a pending notification once the ring is empty. */
int pump_take(pump *p, int drain_first, uint8_t *buf, int buf_len, int32_t *lens, int64_t *stamps,
              uint32_t *ips, uint16_t *ports, int max) {
    int n = 0, used = 0;
    pthread_mutex_lock(&p->lock);
    if (drain_first) drain_socket(p);
    while (n < max && p->ring_count > 0) {
        ring_meta *m = &p->ring[p->ring_head];
        if (used + m->len > buf_len) break;
        memcpy(buf + used, p->ring_data + (size_t)p->ring_head * (size_t)p->ring_bytes,
               (size_t)m->len);
        used += m->len;
        lens[n] = m->len;
        stamps[n] = m->stamp_ns;
        ips[n] = m->ip;
        ports[n] = m->port;
        n++;
        p->ring_head = (p->ring_head + 1) % p->ring_cap;
        p->ring_count--;
    }
    if (p->ring_count == 0 && p->notified) {
        uint64_t value;
        ssize_t ignored = read(p->notify_fd, &value, sizeof value);
        (void)ignored;
        p->notified = 0;
    }
    pthread_mutex_unlock(&p->lock);
    return n;
}

/* sent, send errors, received, ring overflows, thread wake-ups, latest send behind its due
 * time (ns), whether the thread runs at real-time priority. */
void pump_counters(pump *p, int64_t *out) {
    pthread_mutex_lock(&p->lock);
    memcpy(out, p->counters, sizeof p->counters);
    pthread_mutex_unlock(&p->lock);
}

/* Start (or restart) the periodic stream `tag`: `data` every `period_ns` from `first_due_ns` to
 * `ip`:`port`, with the 32-bit counter at `off32` and the 16-bit one at `off16` (little-endian,
 * -1: none) starting at `first32` and `first16` and rising by one per packet. 0, -1 when every
 * stream is taken, -2 when the datagram is longer than a slot or a counter lies outside it. */
int pump_periodic_start(pump *p, int64_t tag, int64_t first_due_ns, int64_t period_ns, uint32_t ip,
                        uint16_t port, const uint8_t *data, int len, int off32, uint32_t first32,
                        int off16, uint16_t first16) {
    if (!periodic_fits(len, p->queue_bytes, off32, off16) || period_ns <= 0) return -2;
    pthread_mutex_lock(&p->lock);
    periodic *s = periodic_slot(p->periodics, tag);
    if (!s) {
        pthread_mutex_unlock(&p->lock);
        return -1;
    }
    periodic_set(s, tag, first_due_ns, period_ns, ip, port, data, len, off32, first32, off16,
                 first16);
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
    periodic *s = periodic_find(p->periodics, tag);
    int result = !s ? -1 : !periodic_fits(len, p->queue_bytes, s->off32, s->off16) ? -2 : 0;
    if (result == 0) {
        memcpy(s->data, data, (size_t)len);
        s->len = len;
    }
    pthread_mutex_unlock(&p->lock);
    return result;
}

/* The periodic stream `tag`'s next packet: its counters and due time into *next32, *next16 and
 * *next_due_ns; with `stop`, the stream ends (that packet is not sent). 0, or -1 when there is
 * no such stream. */
int pump_periodic_next(pump *p, int64_t tag, int stop, uint32_t *next32, uint16_t *next16,
                       int64_t *next_due_ns) {
    pthread_mutex_lock(&p->lock);
    periodic *s = periodic_find(p->periodics, tag);
    if (s) {
        if (stop) s->active = 0;
        *next32 = s->count32;
        *next16 = s->count16;
        *next_due_ns = s->due_ns;
    }
    pthread_mutex_unlock(&p->lock);
    return s ? 0 : -1;
}
