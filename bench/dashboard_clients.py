#!/usr/bin/env python3
"""dashboard_clients.py - does watching the farm slow it down? (issue 16)

Starts tessera-coordinator --http with two 1-thread workers on loopback and
renders the same job repeatedly, alternating (ABBA): no HTTP clients, and N
event-stream clients that read everything plus one that reads nothing.
Prints each run's wall time, tile throughput, the CPU time the coordinator
and the workers spent on it (from /proc, so that other load on the machine
does not count) and the coordinator's resident memory; then the medians,
the peak RSS and the load average. Usage: bench/dashboard_clients.py
BUILD/bin [N] [RUNS]"""
import os, socket, statistics, subprocess, sys, tempfile, threading, time, selectors

bindir = sys.argv[1]
nclients = int(sys.argv[2]) if len(sys.argv) > 2 else 200
runs = int(sys.argv[3]) if len(sys.argv) > 3 else 3

from farmkit import free_port

port, http = free_port(), free_port()
d = tempfile.mkdtemp(prefix="tessera-dash-bench-")
coord = subprocess.Popen([f"{bindir}/tessera-coordinator", "--listen", f"127.0.0.1:{port}", "--data-dir", d,
                          "--http", f"127.0.0.1:{http}"], stderr=open(f"{d}/coord.log", "w"))
time.sleep(0.5)
workers = [subprocess.Popen([f"{bindir}/tessera-worker", "--connect", f"127.0.0.1:{port}", "--threads", "1",
                             "--name", f"w{i}"], stderr=subprocess.DEVNULL) for i in range(2)]
time.sleep(0.5)
env = dict(os.environ, TESSERA_COORDINATOR=f"127.0.0.1:{port}")
job = ["scenes/cornell-box.json", "--width", "256", "--height", "256", "--spp", "64", "--tile-size", "16", "--wait"]

TILES = 256  # 256x256 in 16 px tiles
HZ = os.sysconf("SC_CLK_TCK")

def cpu(pid):
    f = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / HZ  # utime + stime

def rss_kib(pid):
    return int([l for l in open(f"/proc/{pid}/status") if l.startswith("VmRSS")][0].split()[1])

def render():
    """Wall seconds, coordinator CPU seconds, workers' CPU seconds of one job."""
    c0, w0, t = cpu(coord.pid), sum(cpu(w.pid) for w in workers), time.monotonic()
    subprocess.run([f"{bindir}/tessera", "submit"] + job, env=env, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return time.monotonic() - t, cpu(coord.pid) - c0, sum(cpu(w.pid) for w in workers) - w0

def open_stream(rcvbuf=None):
    s = socket.socket()
    if rcvbuf: s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    s.connect(("127.0.0.1", http))
    s.sendall(f"GET /api/events HTTP/1.1\r\nHost: 127.0.0.1:{http}\r\n\r\n".encode())
    return s

times = {"none": [], "clients": []}
rss = []
print(f"load average at the start: {os.getloadavg()}", flush=True)
received = [0]
def with_clients():
    """One render with nclients reading streams and one stalled stream open."""
    # the readers run in a child at nice 19, so that their own CPU time is
    # not what is measured; the stalled client never reads at all
    rd, wr = os.pipe()
    child = os.fork()
    if child == 0:
        os.nice(19)
        readers = [open_stream() for _ in range(nclients)]
        os.write(wr, b"r")
        sel = selectors.DefaultSelector()
        for s in readers: s.setblocking(False); sel.register(s, selectors.EVENT_READ)
        deadline = time.monotonic() + 600
        while time.monotonic() < deadline:
            for k, _ in sel.select(0.1):
                try:
                    if not k.fileobj.recv(65536): os._exit(0)
                except (BlockingIOError, ConnectionError): pass
        os._exit(0)
    os.read(rd, 1)
    stalled = open_stream(rcvbuf=4096)
    times["clients"].append(render())
    rss.append(rss_kib(coord.pid))
    os.kill(child, 15); os.waitpid(child, 0)
    stalled.close()

for r in range(runs):
    # ABBA: the order alternates, so that load rising or falling on a shared
    # machine does not favour one side
    if r % 2 == 0:
        times["none"].append(render())
        with_clients()
    else:
        with_clients()
        times["none"].append(render())
    for k in ("none", "clients"):
        wall, ccpu, wcpu = times[k][-1]
        print(f"run {r} {k:7s}: {wall:6.2f} s wall, {TILES / wall:5.1f} tiles/s, coordinator CPU {ccpu:5.2f} s, "
              f"workers CPU {wcpu:6.2f} s", flush=True)
    print(f"run {r}: coordinator RSS {rss[-1]} KiB with {nclients}+1 clients open; load {os.getloadavg()[0]:.1f}",
          flush=True)
hwm = int([l for l in open(f"/proc/{coord.pid}/status") if l.startswith("VmHWM")][0].split()[1])
for w in workers: w.terminate()
coord.terminate(); coord.wait()
med = {k: [statistics.median(x[i] for x in v) for i in range(3)] for k, v in times.items()}
m0, m1 = med["none"][0], med["clients"][0]
print(f"median wall: no clients {m0:.2f} s, with clients {m1:.2f} s ({100 * (m1 / m0 - 1):+.1f}%); "
      f"tiles/s {TILES / m0:.1f} vs {TILES / m1:.1f}")
print(f"median CPU: coordinator {med['none'][1]:.2f} s vs {med['clients'][1]:.2f} s; "
      f"workers {med['none'][2]:.2f} s vs {med['clients'][2]:.2f} s")
print(f"coordinator RSS with clients open: {min(rss)}-{max(rss)} KiB over the runs; peak {hwm} KiB; "
      f"load average at the end: {os.getloadavg()}")
