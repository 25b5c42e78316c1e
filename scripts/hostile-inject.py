#!/usr/bin/env python3
"""Hostile traffic on a veth end for scripts/netns-test.sh part 4.

Runs in the slave namespace next to `ecdc emulate`: watches the EtherCAT frames leaving the
interface (the emulator's replies to the master) and, for every Nth one, sends copies that a
master must not act on, plus frames of its own:

  duplicate       the reply again (its index is no longer in flight: stale)
  command         the reply with the first datagram's command byte changed
  truncated       the first 20 bytes of the reply
  short_ecat      the reply with its ECAT length field larger than the frame
  vlan            the reply with an 802.1Q tag (VLAN 5) before the EtherType
  other_ethertype the reply's payload as IPv4 (0x0800)
  other_master    a BRD request from another MAC, not processed by any slave
  garbage         60 bytes of EtherType 0x88A4 with a random body

Starts after --delay, stops --seconds later; prints a JSON object with how many of each it sent on stdout.
Standard library only (AF_PACKET raw sockets, Linux, root).
"""

import argparse
import collections
import json
import os
import random
import select
import socket
import struct
import time

ETH_P_ALL = 0x0003
ECAT = 0x88A4
PACKET_OUTGOING = 4


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--iface", required=True)
    ap.add_argument("--seconds", type=float, required=True)
    ap.add_argument("--every", type=int, default=20, help="act on every Nth reply")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--delay", type=float, default=0.0, help="seconds before the first injection")
    a = ap.parse_args()
    rng = random.Random(a.seed)
    s = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
    s.bind((a.iface, 0))
    sent = {k: 0 for k in ("duplicate", "command", "truncated", "short_ecat", "vlan",
                           "other_ethertype", "other_master", "garbage")}
    errors = 0
    seen = 0
    recent = collections.deque(maxlen=256)
    start = time.monotonic() + a.delay
    end = start + a.seconds

    def send(kind, frame):
        nonlocal errors
        recent.append(bytes(frame))
        try:
            s.send(frame)
            sent[kind] += 1
        except OSError:
            errors += 1

    while True:
        left = end - time.monotonic()
        if left <= 0:
            break
        r, _, _ = select.select([s], [], [], min(left, 0.1))
        if not r:
            continue
        frame, addr = s.recvfrom(65535)
        # Only what leaves this end (the emulator's replies), never our own injections:
        # they are sent on this socket too and would otherwise feed back.
        if addr[2] != PACKET_OUTGOING or len(frame) < 16:
            continue
        if struct.unpack("!H", frame[12:14])[0] != ECAT:
            continue
        if frame in recent:
            continue
        if time.monotonic() < start:
            continue
        seen += 1
        if seen % a.every:
            continue
        send("duplicate", frame)
        f = bytearray(frame)
        if len(f) > 16:
            f[16] = 0x05 if f[16] != 0x05 else 0x07  # FPRD <-> BRD
            send("command", bytes(f))
        send("truncated", frame[:20])
        f = bytearray(frame)
        f[14] = 0xFF
        f[15] = (f[15] & 0xF0) | 0x07
        send("short_ecat", bytes(f))
        send("vlan", frame[:12] + b"\x81\x00\x00\x05" + frame[12:])
        send("other_ethertype", frame[:12] + b"\x08\x00" + frame[14:])
        # Another master: its own unicast MAC with bit 1 of the first octet clear (slaves
        # set that bit on the way back), a BRD of 0x0130 not processed by any slave.
        other = (b"\xff" * 6 + b"\x04\xde\xad\xbe\xef\x01" + struct.pack("!H", ECAT)
                 + struct.pack("<H", 12 | 0x1000)
                 + bytes([0x07, 0x42]) + struct.pack("<HHHH", 0, 0x0130, 2, 0)
                 + b"\x00\x00" + b"\x00\x00")
        send("other_master", other.ljust(60, b"\x00"))
        send("garbage", frame[:12] + struct.pack("!H", ECAT)
             + bytes(rng.randrange(256) for _ in range(46)))
    print(json.dumps({"replies_seen": seen, "sent": sent, "send_errors": errors,
                      "pid": os.getpid()}))


if __name__ == "__main__":
    main()
