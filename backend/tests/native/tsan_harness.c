/* The cyclic pump under ThreadSanitizer (`make native-tsan`, part of `make test`).
 *
 * Built with -fsanitize=thread together with ../../src/cobot_hmi/native/cyclic_pump.c, it starts
 * a pump on a loopback UDP socket and, while the pump's thread sends and reads, drives every call
 * of the interface from three threads at once: a feeder (queue, cancel, periodic streams and
 * their templates, configure), a reader (take, counters, queued) and a peer that sends datagrams
 * to the pump's socket; then it stops and frees the pump. Any report by ThreadSanitizer fails the
 * run (exit code 66); so does a pump that sent or received nothing (the harness must really have
 * exercised it). Only loopback (127.0.0.1) is used.
 */
#define _GNU_SOURCE
#include <arpa/inet.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "cyclic_pump.h"

#define LOOPBACK 0x7F000001u
#define ROUNDS 400
#define SLOT_BYTES 64

static pump *the_pump;
static uint16_t pump_port, peer_port;
static atomic_int done;

static int udp_socket(uint16_t *port) {
    int fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK, 0);
    struct sockaddr_in at = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(LOOPBACK)};
    socklen_t len = sizeof at;
    if (fd < 0 || bind(fd, (struct sockaddr *)&at, sizeof at) != 0 ||
        getsockname(fd, (struct sockaddr *)&at, &len) != 0) {
        perror("udp socket");
        exit(2);
    }
    *port = ntohs(at.sin_port);
    return fd;
}

static void pause_us(long us) {
    struct timespec t = {0, us * 1000};
    nanosleep(&t, NULL);
}

static void *feeder(void *arg) {
    (void)arg;
    uint8_t packet[16] = {0};
    for (int i = 0; i < ROUNDS; i++) {
        int64_t now = pump_now_ns();
        packet[0] = (uint8_t)i;
        pump_queue(the_pump, now + 100000 * (i % 5), LOOPBACK, peer_port, packet, sizeof packet, i % 3);
        if (i % 7 == 0) {
            int64_t first = 0;
            pump_cancel(the_pump, 2, now, &first);
        }
        if (i % 50 == 0) {
            pump_periodic_start(the_pump, 1 + i % 2, now, 200000, LOOPBACK, peer_port, packet,
                                sizeof packet, 0, (uint32_t)i, 4, (uint16_t)i);
            pump_configure(the_pump, i % 100 == 0, i % 100 == 0 ? 0 : 500000, 2000000);
        }
        if (i % 10 == 0) pump_periodic_data(the_pump, 1, packet, sizeof packet);
        if (i % 90 == 0) {
            uint32_t n32;
            uint16_t n16;
            int64_t due;
            pump_periodic_next(the_pump, 2, 1, &n32, &n16, &due);
        }
        pause_us(50);
    }
    return NULL;
}

static void *reader(void *arg) {
    (void)arg;
    uint8_t buf[8 * SLOT_BYTES];
    int32_t lens[8];
    int64_t stamps[8];
    uint32_t ips[8];
    uint16_t ports[8];
    int64_t counters[C_COUNT];
    while (!atomic_load(&done)) {
        pump_take(the_pump, 1, buf, sizeof buf, lens, stamps, ips, ports, 8);
        pump_counters(the_pump, counters);
        pump_queued(the_pump, 1); /* no pause: as often as it can, to meet the thread */
    }
    return NULL;
}

static void *peer(void *arg) {
    int fd = *(int *)arg;
    struct sockaddr_in to = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(LOOPBACK),
                             .sin_port = htons(pump_port)};
    uint8_t data[SLOT_BYTES + 8] = {0}; /* some longer than a slot */
    uint8_t sink[128];
    for (int i = 0; i < ROUNDS; i++) {
        sendto(fd, data, (size_t)(i % 3 == 0 ? sizeof data : 8), 0, (struct sockaddr *)&to, sizeof to);
        while (recv(fd, sink, sizeof sink, MSG_DONTWAIT) > 0) {
        }
        pause_us(50);
    }
    return NULL;
}

int main(void) {
    int pump_fd = udp_socket(&pump_port);
    int peer_fd = udp_socket(&peer_port);
    int one = 1;
    setsockopt(pump_fd, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof one);
    the_pump = pump_new(pump_fd, 64, SLOT_BYTES, 32, SLOT_BYTES);
    if (!the_pump || pump_start(the_pump) != 0 || pump_start(the_pump) != 0) {
        fprintf(stderr, "cannot start the pump\n");
        return 2;
    }
    pthread_t threads[3];
    pthread_create(&threads[0], NULL, feeder, NULL);
    pthread_create(&threads[1], NULL, reader, NULL);
    pthread_create(&threads[2], NULL, peer, &peer_fd);
    pthread_join(threads[0], NULL);
    pthread_join(threads[2], NULL);
    pause_us(5000);
    atomic_store(&done, 1);
    pthread_join(threads[1], NULL);

    int64_t counters[C_COUNT];
    pump_counters(the_pump, counters);
    pump_stop(the_pump);
    pump_stop(the_pump); /* twice: nothing */
    pump_free(the_pump);
    close(pump_fd);
    close(peer_fd);
    printf("cyclic pump under ThreadSanitizer: sent %lld, received %lld, wake-ups %lld\n",
           (long long)counters[C_SENT], (long long)counters[C_RECEIVED],
           (long long)counters[C_WAKEUPS]);
    if (counters[C_SENT] == 0 || counters[C_RECEIVED] == 0) {
        fprintf(stderr, "the pump sent or received nothing: the harness exercised nothing\n");
        return 1;
    }
    return 0;
}
