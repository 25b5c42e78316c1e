/*
 * c_master: a minimal EtherCAT DC master in plain C on the ecdc C API.
 *
 * It opens an AF_PACKET raw socket bound to EtherType 0x88A4 on one interface, brings the
 * Distributed Clocks up through libecdc_ffi and runs the cyclic loop for a number of seconds,
 * printing every event and a final summary line:
 *
 *   summary: lock_reached=yes locked_at_end=yes frames_sent=... frames_received=... rtt_us_min=... ...
 *
 * The exit status is 0 when the machine reached lock during the run, 1 otherwise, 2 on a setup
 * error. `locked_at_end` tells whether it still held at the end (a loaded host that misses
 * replies for 5 cycles in a row makes the machine restart, which the summary counts).
 *
 * Time handed to the machine is CLOCK_REALTIME converted to ns since 2000-01-01 (the DC
 * epoch); sleeping is clock_nanosleep on the same clock with absolute deadlines, waiting for
 * a reply is ppoll on the socket.
 *
 * Options:
 *   -d SECONDS  run time (default 5)
 *   -s          place the machine in caller storage (ecdc_machine_init) instead of
 *               ecdc_machine_new
 *   -i          once cyclic, build the cyclic frame here: a host datagram (BRD 0x0130, AL
 *               status, index 0x01, outside ecdc's 0x80..0xFF) plus ecdc's datagrams appended
 *               by ecdc_poll_transmit_into, sent every cycle_ns at this program's cadence
 *   -q          print only the summary and faults
 *
 * Build (see docs/c-api.md):
 *   cargo build --release -p ecdc-ffi
 *   cc -std=c99 -Wall -Wextra -Werror -pedantic -O2 -Iffi/include ffi/examples/c_master.c \
 *      target/release/libecdc_ffi.a -lpthread -ldl -lm -o c_master
 * Run (needs CAP_NET_RAW):  ./c_master -d 5 eth1
 */
/* AF_PACKET, struct ifreq and ppoll are Linux interfaces. */
#define _GNU_SOURCE

#include <arpa/inet.h>
#include <errno.h>
#include <linux/if_packet.h>
#include <net/if.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "ecdc.h"

/* Seconds from 1970-01-01 to the DC epoch 2000-01-01 00:00 UTC. */
#define UNIX_TO_DC_EPOCH_S 946684800ULL
#define NS_PER_S 1000000000ULL
#define ETHERTYPE_ECAT 0x88A4
#define FRAME_MAX 1514
/* Round-trip samples kept for the summary: 10 minutes of 1 ms cycles. */
#define RTT_SAMPLES_MAX 600000
/* Frames that may await a reply at once; ecdc never has more than a few in flight. */
#define FIFO_LEN 64
/* The host's own datagram index in -i mode; ecdc owns 0x80..0xFF by default. */
#define HOST_INDEX 0x01
#define CMD_BRD 7

static volatile sig_atomic_t stop_requested;
static uint32_t rtt_ns[RTT_SAMPLES_MAX];
static size_t rtt_count;

static void on_signal(int sig) {
    (void)sig;
    stop_requested = 1;
}

/* The master's clock in the DC epoch. */
static uint64_t dc_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return ((uint64_t)ts.tv_sec - UNIX_TO_DC_EPOCH_S) * NS_PER_S + (uint64_t)ts.tv_nsec;
}

static struct timespec dc_to_realtime(uint64_t dc) {
    struct timespec ts;
    ts.tv_sec = (time_t)(dc / NS_PER_S + UNIX_TO_DC_EPOCH_S);
    ts.tv_nsec = (long)(dc % NS_PER_S);
    return ts;
}

static uint64_t mono_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * NS_PER_S + (uint64_t)ts.tv_nsec;
}

static int open_socket(const char *ifname) {
    int fd = socket(AF_PACKET, SOCK_RAW, htons(ETHERTYPE_ECAT));
    if (fd < 0) {
        fprintf(stderr, "c_master: socket(AF_PACKET): %s (needs CAP_NET_RAW)\n", strerror(errno));
        return -1;
    }
    unsigned idx = if_nametoindex(ifname);
    if (idx == 0) {
        fprintf(stderr, "c_master: no interface named \"%s\"\n", ifname);
        close(fd);
        return -1;
    }
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    strncpy(ifr.ifr_name, ifname, IFNAMSIZ - 1);
    if (ioctl(fd, SIOCGIFFLAGS, &ifr) == 0 && !(ifr.ifr_flags & IFF_UP)) {
        fprintf(stderr, "c_master: %s is down (ip link set %s up)\n", ifname, ifname);
        close(fd);
        return -1;
    }
    struct sockaddr_ll sll;
    memset(&sll, 0, sizeof sll);
    sll.sll_family = AF_PACKET;
    sll.sll_protocol = htons(ETHERTYPE_ECAT);
    sll.sll_ifindex = (int)idx;
    if (bind(fd, (struct sockaddr *)&sll, sizeof sll) < 0) {
        fprintf(stderr, "c_master: bind(%s): %s\n", ifname, strerror(errno));
        close(fd);
        return -1;
    }
    /* Drop what queued between socket() and bind() (frames of any interface). */
    unsigned char scratch[FRAME_MAX];
    while (recv(fd, scratch, sizeof scratch, MSG_DONTWAIT) > 0) {
    }
    return fd;
}

/* Send times of frames awaiting their reply, oldest first (a veth or a line keeps order). */
static uint64_t fifo[FIFO_LEN];
static size_t fifo_head, fifo_len;

static void fifo_push(uint64_t t) {
    if (fifo_len == FIFO_LEN) { /* the oldest was lost */
        fifo_head = (fifo_head + 1) % FIFO_LEN;
        fifo_len--;
    }
    fifo[(fifo_head + fifo_len) % FIFO_LEN] = t;
    fifo_len++;
}

static void fifo_pop_rtt(uint64_t now) {
    if (fifo_len == 0) {
        return;
    }
    uint64_t sent = fifo[fifo_head];
    fifo_head = (fifo_head + 1) % FIFO_LEN;
    fifo_len--;
    if (rtt_count < RTT_SAMPLES_MAX) {
        uint64_t d = now - sent;
        rtt_ns[rtt_count++] = d > UINT32_MAX ? UINT32_MAX : (uint32_t)d;
    }
}

struct counters {
    uint64_t sent, received, send_errors, host_frames, host_wkc_ok;
    unsigned locks, faults;
};

static int send_frame(int fd, const uint8_t *buf, size_t len, struct counters *c) {
    if (send(fd, buf, len, 0) != (ssize_t)len) {
        c->send_errors++;
        return -1;
    }
    c->sent++;
    fifo_push(mono_now());
    return 0;
}

/* Hands every queued frame to the machine, waiting for more while the machine awaits a reply
 * and the DC time `until` has not passed. */
static unsigned receive_until(int fd, ecdc_machine *m, uint64_t until, struct counters *c,
                              uint8_t *rx, uint16_t host_wkc_at) {
    unsigned got = 0;
    for (;;) {
        ssize_t n = recv(fd, rx, FRAME_MAX, MSG_DONTWAIT);
        if (n > 0) {
            fifo_pop_rtt(mono_now());
            c->received++;
            if (host_wkc_at != 0 && (size_t)n >= (size_t)host_wkc_at + 2u) {
                /* In -i mode the frame starts with our BRD: its WKC counts the slaves. */
                uint16_t wkc = (uint16_t)(rx[host_wkc_at] | (rx[host_wkc_at + 1] << 8));
                if (wkc > 0 && wkc == ecdc_slave_count(m)) {
                    c->host_wkc_ok++;
                }
            }
            ecdc_handle_frame(m, dc_now(), rx, (size_t)n);
            got++;
            continue;
        }
        uint64_t now = dc_now();
        if (!ecdc_is_awaiting_reply(m) || now >= until || stop_requested) {
            return got;
        }
        uint64_t wait = until - now;
        struct timespec ts = {(time_t)(wait / NS_PER_S), (long)(wait % NS_PER_S)};
        struct pollfd p = {fd, POLLIN, 0};
        if (ppoll(&p, 1, &ts, NULL) < 0 && errno != EINTR) {
            return got;
        }
    }
}

static void print_events(ecdc_machine *m, int quiet, struct counters *c) {
    ecdc_event ev;
    while (ecdc_poll_event(m, &ev)) {
        switch (ev.kind) {
        case ECDC_EVENT_LOCKED:
            c->locks++;
            break;
        case ECDC_EVENT_ERROR:
            c->faults++;
            break;
        case ECDC_EVENT_NONE:
        case ECDC_EVENT_SLAVES_FOUND:
        case ECDC_EVENT_DELAYS_MEASURED:
        case ECDC_EVENT_OFFSETS_WRITTEN:
        case ECDC_EVENT_DRIFT_CONVERGED:
        case ECDC_EVENT_SYNC_STARTED:
        case ECDC_EVENT_LOCK_LOST:
        case ECDC_EVENT_DELAYS_UPDATED:
        case ECDC_EVENT_RESTARTING:
        case ECDC_EVENT_OTHER:
        default: /* a kind this program predates */
            break;
        }
        if (!quiet || ev.kind == ECDC_EVENT_ERROR) {
            printf("event: %s\n", ev.text);
        }
        if (!quiet && ev.kind == ECDC_EVENT_LOCKED) {
            uint32_t n = ecdc_slave_count(m);
            for (uint32_t i = 0; i < n; i++) {
                ecdc_slave s;
                if (ecdc_slave_info(m, i, &s) == ECDC_OK) {
                    printf("  slave %u: station 0x%04x delay %u ns%s\n", (unsigned)i,
                           (unsigned)s.station, (unsigned)s.delay_ns,
                           s.is_reference ? " (reference)" : "");
                }
            }
        }
    }
}

static int cmp_u32(const void *a, const void *b) {
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

static double us(uint32_t ns) { return (double)ns / 1000.0; }

int main(int argc, char **argv) {
    double seconds = 5.0;
    int use_storage = 0, embed = 0, quiet = 0, opt;
    while ((opt = getopt(argc, argv, "d:siq")) != -1) {
        switch (opt) {
        case 'd': seconds = atof(optarg); break;
        case 's': use_storage = 1; break;
        case 'i': embed = 1; break;
        case 'q': quiet = 1; break;
        default:
            fprintf(stderr, "usage: %s [-d SECONDS] [-s] [-i] [-q] IFACE\n", argv[0]);
            return 2;
        }
    }
    if (optind + 1 != argc || seconds <= 0.0) {
        fprintf(stderr, "usage: %s [-d SECONDS] [-s] [-i] [-q] IFACE\n", argv[0]);
        return 2;
    }
    const char *ifname = argv[optind];

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);

    ecdc_config cfg;
    ecdc_config_default(&cfg);
    ecdc_machine *m = NULL;
    void *storage = NULL;
    ecdc_status st;
    if (use_storage) {
        if (posix_memalign(&storage, ecdc_machine_align(), ecdc_machine_size()) != 0) {
            fprintf(stderr, "c_master: out of memory\n");
            return 2;
        }
        st = ecdc_machine_init(storage, ecdc_machine_size(), &cfg, &m);
    } else {
        st = ecdc_machine_new(&cfg, &m);
    }
    if (st != ECDC_OK) {
        fprintf(stderr, "c_master: creating the machine: %s\n", ecdc_strerror((int)st));
        free(storage);
        return 2;
    }
    int fd = open_socket(ifname);
    if (fd < 0) {
        ecdc_machine_free(m);
        free(storage);
        return 2;
    }
    if (!quiet) {
        printf("c_master: ecdc %s on %s, capacity %u slaves, %s, %.1f s%s\n", ecdc_version(),
               ifname, (unsigned)ecdc_machine_capacity(m),
               use_storage ? "caller storage" : "ecdc_machine_new", seconds,
               embed ? ", host-built cyclic frames" : "");
    }

    static uint8_t tx[FRAME_MAX], rx[FRAME_MAX];
    struct counters c;
    memset(&c, 0, sizeof c);
    uint64_t t0 = dc_now();
    uint64_t end = t0 + (uint64_t)(seconds * 1e9);
    uint64_t next_cycle = 0;
    ecdc_start(m, t0);

    while (!stop_requested) {
        uint64_t now = dc_now();
        if (now >= end) {
            break;
        }
        ecdc_handle_timeout(m, now);
        uint16_t host_wkc_at = 0;
        if (embed && ecdc_state(m) == ECDC_STATE_CYCLIC) {
            /* The host's cadence is the cycle: one frame per cycle_ns carrying our own
             * datagram and ecdc's. */
            if (next_cycle == 0) {
                next_cycle = now;
            }
            if (now >= next_cycle) {
                ecdc_frame f;
                ecdc_datagram_slot slot;
                bool appended = false;
                size_t len = 0;
                if (ecdc_frame_init(&f, tx, sizeof tx) == ECDC_OK &&
                    ecdc_frame_push(&f, CMD_BRD, HOST_INDEX, 0, 0x0130, NULL, 2, &slot) == ECDC_OK &&
                    ecdc_poll_transmit_into(m, now, &f, &appended) == ECDC_OK &&
                    ecdc_frame_finish(&f, &len) == ECDC_OK) {
                    if (send_frame(fd, tx, len, &c) == 0) {
                        c.host_frames++;
                    }
                    host_wkc_at = (uint16_t)slot.wkc_offset;
                }
                next_cycle += cfg.cycle_ns;
                if (next_cycle < now) { /* overrun: skip the missed cycles */
                    next_cycle = now + cfg.cycle_ns;
                }
            }
        } else {
            next_cycle = 0;
            size_t n;
            while ((n = ecdc_poll_transmit(m, now, tx, sizeof tx)) > 0) {
                send_frame(fd, tx, n, &c);
            }
        }
        print_events(m, quiet, &c);

        uint64_t deadline;
        if (embed && ecdc_state(m) == ECDC_STATE_CYCLIC) {
            deadline = next_cycle;
        } else if (!ecdc_poll_timeout(m, &deadline)) {
            deadline = now + cfg.cycle_ns; /* nothing scheduled (idle, failed) */
        }
        if (deadline > end) {
            deadline = end;
        }
        /* Read what arrived, waiting on the socket while a reply is due. A reply may let the
         * machine send at once (no deadline then), so go round again before sleeping. */
        unsigned got = receive_until(fd, m, deadline, &c, rx, host_wkc_at);
        print_events(m, quiet, &c);
        if (got == 0 && !ecdc_is_awaiting_reply(m)) {
            fifo_len = 0; /* replies still out were given up by the machine */
            if (deadline > dc_now()) {
                struct timespec ts = dc_to_realtime(deadline);
                clock_nanosleep(CLOCK_REALTIME, TIMER_ABSTIME, &ts, NULL);
            }
        }
    }

    ecdc_stats s;
    ecdc_get_stats(m, &s);
    uint32_t bound = 0;
    bool has_bound = ecdc_diff_bound_ns(m, &bound);
    bool locked = ecdc_is_locked(m);
    qsort(rtt_ns, rtt_count, sizeof rtt_ns[0], cmp_u32);
    uint32_t rmin = 0, rmed = 0, rp99 = 0, rmax = 0;
    if (rtt_count > 0) {
        rmin = rtt_ns[0];
        rmed = rtt_ns[rtt_count / 2];
        rp99 = rtt_ns[(rtt_count * 99) / 100];
        rmax = rtt_ns[rtt_count - 1];
    }
    printf("summary: lock_reached=%s locked_at_end=%s state=%s slaves=%u frames_sent=%llu frames_received=%llu "
           "rtt_us_min=%.1f rtt_us_median=%.1f rtt_us_p99=%.1f rtt_us_max=%.1f "
           "lock_frames=%lld bound_ns=%lld cycles=%llu lost_cycles=%llu timeouts=%llu "
           "restarts=%llu faults=%u host_frames=%llu host_wkc_ok=%llu send_errors=%llu\n",
           c.locks > 0 ? "yes" : "no", locked ? "yes" : "no", ecdc_state_name((int)ecdc_state(m)),
           (unsigned)ecdc_slave_count(m), (unsigned long long)c.sent,
           (unsigned long long)c.received, us(rmin), us(rmed), us(rp99), us(rmax),
           s.has_lock_frames ? (long long)s.lock_frames : -1LL,
           has_bound ? (long long)bound : -1LL, (unsigned long long)s.cycles,
           (unsigned long long)s.lost_cycles, (unsigned long long)s.timeouts,
           (unsigned long long)s.restarts, c.faults, (unsigned long long)c.host_frames,
           (unsigned long long)c.host_wkc_ok, (unsigned long long)c.send_errors);

    close(fd);
    ecdc_machine_free(m);
    free(storage);
    return c.locks > 0 ? 0 : 1;
}
