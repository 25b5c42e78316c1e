/* A minimal cyclic EtherCAT master in plain C, the yardstick for `ecdc run`'s loop at fast
 * cycles (docs/runtime.md, "Fast cycles"): what the operating system and a raw socket allow
 * without any protocol work. Each cycle it sleeps to an absolute deadline (clock_nanosleep,
 * CLOCK_MONOTONIC), sends one 60-byte frame with a BRD of AL status 0x0130 on an AF_PACKET
 * socket, and waits for the reply until the next deadline. It measures exactly what `ecdc run`
 * reports for its own loop: wake lateness (woken - deadline), overruns (a wake more than one
 * period late: those deadlines are skipped, not caught up), lost cycles (no reply before the
 * next deadline) and the round trip.
 *
 * Build: cc -O2 -Wall -Wextra -o cyclic-probe scripts/cyclic-probe.c
 * Run:   cyclic-probe IFACE PERIOD_US SECONDS [--rt CPU PRIORITY]
 *        (root or CAP_NET_RAW; --rt: SCHED_FIFO, mlockall, pinned to CPU)
 * Output: one JSON object on stdout.
 */
#define _GNU_SOURCE
#include <arpa/inet.h>
#include <errno.h>
#include <linux/if_packet.h>
#include <net/ethernet.h>
#include <net/if.h>
#include <poll.h>
#include <sched.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#define ETHERTYPE_ECAT 0x88A4
#define FRAME_LEN 60
#define NS_PER_S 1000000000LL

static int64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * NS_PER_S + ts.tv_nsec;
}

static void sleep_until(int64_t t)
{
    struct timespec ts = { .tv_sec = t / NS_PER_S, .tv_nsec = t % NS_PER_S };
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR) {
    }
}

static int cmp_i64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

/* Nearest-rank percentile of a sorted array, in microseconds. */
static double pct_us(const int64_t *v, size_t n, double p)
{
    if (n == 0)
        return -1.0;
    size_t k = (size_t)(p * (double)n + 0.999999);
    if (k < 1)
        k = 1;
    if (k > n)
        k = n;
    return (double)v[k - 1] / 1000.0;
}

/* One BRD 0x0130 (2 bytes) datagram with index `idx` in a padded 60-byte frame. */
static void build_frame(uint8_t *f, const uint8_t src[6], uint8_t idx)
{
    memset(f, 0, FRAME_LEN);
    memset(f, 0xFF, 6);
    memcpy(f + 6, src, 6);
    f[12] = ETHERTYPE_ECAT >> 8;
    f[13] = ETHERTYPE_ECAT & 0xFF;
    uint16_t dlen = 2, ecat_len = 10 + dlen + 2;
    uint16_t hdr = (uint16_t)(ecat_len | (1u << 12));
    f[14] = hdr & 0xFF;
    f[15] = hdr >> 8;
    uint8_t *d = f + 16;
    d[0] = 0x07; /* BRD */
    d[1] = idx;
    d[4] = 0x30; /* ADO 0x0130, little endian */
    d[5] = 0x01;
    d[6] = dlen & 0xFF;
    d[7] = dlen >> 8;
}

int main(int argc, char **argv)
{
    if (argc != 4 && argc != 7) {
        fprintf(stderr, "usage: %s IFACE PERIOD_US SECONDS [--rt CPU PRIORITY]\n", argv[0]);
        return 2;
    }
    const char *iface = argv[1];
    long period_us = strtol(argv[2], NULL, 10);
    double seconds = strtod(argv[3], NULL);
    if (period_us < 50 || period_us > 100000 || seconds <= 0 || seconds > 3600) {
        fprintf(stderr, "PERIOD_US 50..100000, SECONDS 0..3600\n");
        return 2;
    }
    int rt = argc == 7 && strcmp(argv[4], "--rt") == 0;
    if (argc == 7 && !rt) {
        fprintf(stderr, "fifth argument must be --rt\n");
        return 2;
    }
    if (rt) {
        cpu_set_t set;
        CPU_ZERO(&set);
        CPU_SET(atoi(argv[5]), &set);
        if (sched_setaffinity(0, sizeof set, &set) != 0)
            perror("warning: sched_setaffinity");
        struct sched_param sp = { .sched_priority = atoi(argv[6]) };
        if (sched_setscheduler(0, SCHED_FIFO, &sp) != 0)
            perror("warning: SCHED_FIFO");
        if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
            perror("warning: mlockall");
    }

    int s = socket(AF_PACKET, SOCK_RAW, htons(ETHERTYPE_ECAT));
    if (s < 0) {
        perror("socket (needs CAP_NET_RAW)");
        return 1;
    }
    unsigned ifindex = if_nametoindex(iface);
    if (ifindex == 0) {
        perror(iface);
        return 1;
    }
    struct sockaddr_ll sll = { .sll_family = AF_PACKET,
                               .sll_protocol = htons(ETHERTYPE_ECAT),
                               .sll_ifindex = (int)ifindex };
    if (bind(s, (struct sockaddr *)&sll, sizeof sll) != 0) {
        perror("bind");
        return 1;
    }
    int one = 1;
#ifdef PACKET_IGNORE_OUTGOING
    setsockopt(s, SOL_PACKET, PACKET_IGNORE_OUTGOING, &one, sizeof one);
#endif
    (void)one;

    const int64_t period = period_us * 1000;
    const size_t cycles = (size_t)(seconds * 1e9 / (double)period);
    int64_t *wake = calloc(cycles, sizeof *wake);
    int64_t *rtt = calloc(cycles, sizeof *rtt);
    if (!wake || !rtt) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    /* Bit 1 of the first source byte clear: the first slave sets it on the way (processed). */
    const uint8_t src[6] = { 0x00, 0x00, 0x00, 0x00, 0xC0, 0x01 };
    uint8_t tx[FRAME_LEN], rx[1600];
    size_t n_wake = 0, n_rtt = 0;
    uint64_t overruns = 0, lost = 0, sent = 0, stale = 0;

    int64_t deadline = now_ns() + 10 * period;
    for (size_t c = 0; c < cycles; c++) {
        sleep_until(deadline);
        int64_t woke = now_ns();
        wake[n_wake++] = woke - deadline;
        if (woke - deadline > period) {
            /* Late by more than a period: skip the missed deadlines (as ecdc run does). */
            int64_t behind = (woke - deadline) / period;
            overruns += (uint64_t)behind;
            deadline += behind * period;
        }
        uint8_t idx = (uint8_t)c;
        build_frame(tx, src, idx);
        int64_t t_send = now_ns();
        if (send(s, tx, FRAME_LEN, 0) != FRAME_LEN) {
            lost++;
            deadline += period;
            continue;
        }
        sent++;
        int64_t next = deadline + period;
        int got = 0;
        for (;;) {
            int64_t left = next - now_ns();
            if (left <= 0)
                break;
            struct pollfd p = { .fd = s, .events = POLLIN };
            struct timespec to = { .tv_sec = left / NS_PER_S, .tv_nsec = left % NS_PER_S };
            if (ppoll(&p, 1, &to, NULL) <= 0)
                continue;
            struct sockaddr_ll from;
            socklen_t fl = sizeof from;
            ssize_t r = recvfrom(s, rx, sizeof rx, MSG_DONTWAIT, (struct sockaddr *)&from, &fl);
            if (r < 0)
                continue;
            if (from.sll_pkttype == PACKET_OUTGOING)
                continue;
            /* A reply: EtherCAT, the first slave marked it processed (source MAC bit 1). */
            if (r >= 18 && rx[12] == 0x88 && rx[13] == 0xA4 && rx[17] == idx &&
                (rx[6] & 0x02) && rx[16] == 0x07) {
                rtt[n_rtt++] = now_ns() - t_send;
                got = 1;
                break;
            }
            stale++;
        }
        if (!got)
            lost++;
        deadline += period;
    }

    qsort(wake, n_wake, sizeof *wake, cmp_i64);
    qsort(rtt, n_rtt, sizeof *rtt, cmp_i64);
    printf("{\"iface\": \"%s\", \"period_us\": %ld, \"rt\": %s, \"cycles\": %zu, \"sent\": %llu, "
           "\"lost\": %llu, \"stale\": %llu, \"overruns\": %llu, "
           "\"wake_us\": {\"median\": %.1f, \"p99\": %.1f, \"p999\": %.1f, \"max\": %.1f}, "
           "\"rtt_us\": {\"median\": %.1f, \"p99\": %.1f, \"max\": %.1f}}\n",
           iface, period_us, rt ? "true" : "false", cycles, (unsigned long long)sent,
           (unsigned long long)lost, (unsigned long long)stale, (unsigned long long)overruns,
           pct_us(wake, n_wake, 0.5), pct_us(wake, n_wake, 0.99), pct_us(wake, n_wake, 0.999),
           pct_us(wake, n_wake, 1.0), pct_us(rtt, n_rtt, 0.5), pct_us(rtt, n_rtt, 0.99),
           pct_us(rtt, n_rtt, 1.0));
    free(wake);
    free(rtt);
    close(s);
    return 0;
}
