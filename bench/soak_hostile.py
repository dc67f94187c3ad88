#!/usr/bin/env python3
"""soak_hostile.py - one round of hostile clients against a tessera-coordinator
(bench/soak.sh, `make soak`): idle clients after the hello, uploads trickled a
byte at a time, an oversized frame, submits with bad numbers, and garbage in
place of a hello. Prints one line of what the coordinator did with each.

    soak_hostile.py HOST PORT BUILD_ID SECONDS
"""
import json
import socket
import struct
import sys
import time

import wire

HOST, PORT, BUILD, SECONDS = sys.argv[1], int(sys.argv[2]), sys.argv[3], float(sys.argv[4])


def read_frame(s):
    """One frame (kind, body), or None on EOF, reset or timeout."""
    try:
        return wire.read_frame(s)
    except (EOFError, OSError):
        return None


def client():
    """A client after the welcome, or None."""
    try:
        s = socket.create_connection((HOST, PORT), timeout=10)
        if read_frame(s) is None:  # the coordinator speaks first
            s.close()
            return None
        s.sendall(wire.json_frame({"type": "hello", "role": "client", "protocol": 1, "build": BUILD, "name": "hostile",
                          "threads": 1}))
        f = read_frame(s)
        if f is None or b"welcome" not in f[1]:
            s.close()
            return None
        return s
    except OSError:
        return None


def closed_by_peer(s, wait):
    """Whether the coordinator closes s within wait seconds (answers read and dropped)."""
    s.settimeout(wait)
    end = time.time() + wait
    while time.time() < end:
        try:
            if not s.recv(65536):
                return True
        except socket.timeout:
            return False
        except OSError:
            return True
    return False


def main():
    start = time.time()
    results = {}
    idle = [c for c in (client() for _ in range(20)) if c]
    results["idle_opened"] = len(idle)
    trick = [c for c in (client() for _ in range(3)) if c]
    for c in trick:  # a 100 KB scene announced, then a byte at a time
        c.sendall(struct.pack("<I", 100001) + b"S")
    bad = 0
    for fields in ({"seed": "abc"}, {"seed": "-1"}, {"width": -1}, {"spp": 1e30}, {"tile_size": "x"},
                   {"priority": 1e300}, {"name": 7}):
        c = client()
        if not c:
            continue
        m = {"type": "submit", "scene": "0" * 64}
        m.update(fields)
        c.sendall(wire.frame(b"S", b"not a bundle") + wire.json_frame(m))
        f = read_frame(c)
        bad += f is not None and b"error" in f[1]
        c.close()
    results["bad_numbers_refused"] = bad
    over = client()
    if over:  # a frame far past --max-upload
        over.sendall(struct.pack("<I", 0x7FFFFFFF) + b"S")
        results["oversized_closed"] = int(closed_by_peer(over, 10))
        over.close()
    garbage = 0
    for _ in range(5):
        try:
            s = socket.create_connection((HOST, PORT), timeout=10)
            s.sendall(b"\xff" * 64 + b"GET / HTTP/1.0\r\n\r\n")
            garbage += closed_by_peer(s, 10)
            s.close()
        except OSError:
            pass
    results["garbage_closed"] = garbage
    while time.time() - start < SECONDS:  # trickle: one byte a second
        for c in trick:
            try:
                c.sendall(b"x")
            except OSError:
                pass
        time.sleep(1)
    results["trickle_closed"] = sum(closed_by_peer(c, 0.5) for c in trick)
    results["idle_closed"] = sum(closed_by_peer(c, 0.2) for c in idle)
    for c in idle + trick:
        c.close()
    print("hostile: " + ", ".join("%s %d" % kv for kv in results.items()))


main()
