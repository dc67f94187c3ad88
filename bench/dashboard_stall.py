#!/usr/bin/env python3
"""dashboard_stall.py - does a dashboard download hold up the coordinator's
loop (and so every worker and client on it)?

Renders one WIDTH x WIDTH job (1 spp, tests/scenes/cornell-small.json) with
a 2-thread worker, then downloads its EXR from the dashboard while asking
/healthz over and over on another connection. Prints the download's time
and size, how many /healthz were answered meanwhile and the slowest, and
the coordinator's own "longest iteration" log line (which also counts the
job's end). With "nodownload" the job only renders and ends, so the
longest iteration is the job's end (its image written). Usage:
bench/dashboard_stall.py BUILD/bin [WIDTH] [nodownload]"""
import http.client, subprocess, sys, tempfile, threading, time

from farmkit import free_port, render_job

bindir = sys.argv[1]
width = int(sys.argv[2]) if len(sys.argv) > 2 else 2048
download = not (len(sys.argv) > 3 and sys.argv[3] == "nodownload")


d = tempfile.mkdtemp(prefix="tessera-stall-")
port, web = free_port(), free_port()
coord = subprocess.Popen([f"{bindir}/tessera-coordinator", "--listen", f"127.0.0.1:{port}", "--data-dir", d,
                          "--http", f"127.0.0.1:{web}"], stderr=open(f"{d}/coord.log", "w"))
time.sleep(0.5)
t = time.monotonic()
render_job(bindir, port, "tests/scenes/cornell-small.json", width)
print(f"rendered {width}x{width} in {time.monotonic() - t:.1f} s")


def get(path):
    c = http.client.HTTPConnection("127.0.0.1", web, timeout=300)
    c.request("GET", path)
    r = c.getresponse()
    body = r.read()
    c.close()
    return r.status, body


done = []


def fetch():
    t0 = time.monotonic()
    status, body = get("/api/jobs/1/image.exr")
    done.append((time.monotonic() - t0, status, len(body)))


if download:
    th = threading.Thread(target=fetch)
    th.start()
    lat = []
    while th.is_alive():
        t0 = time.monotonic()
        get("/healthz")
        lat.append(time.monotonic() - t0)
    th.join()
    took, status, size = done[0]
    print(f"EXR: status {status}, {size / 1e6:.1f} MB in {took:.2f} s; /healthz meanwhile: {len(lat)} answered, "
          f"the slowest {max(lat or [0]) * 1e3:.1f} ms")
coord.terminate()
coord.wait(60)
for line in open(f"{d}/coord.log"):
    if "longest iteration" in line:
        print("coordinator:", line.split("info: ", 1)[-1].strip())
