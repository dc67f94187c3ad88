#!/usr/bin/env python3
"""dashboard_clients.py - does watching the farm slow it down? (issue 16)

Starts tessera-coordinator --http with two 1-thread workers on loopback and
renders the same job repeatedly, alternating: no HTTP clients, then N
event-stream clients that read everything plus one that reads nothing.
Prints each run's wall time and the medians; the coordinator's RSS at the
end. Usage: bench/dashboard_clients.py BUILD/bin [N] [RUNS]"""
import os, socket, statistics, subprocess, sys, tempfile, threading, time, selectors

bindir = sys.argv[1]
nclients = int(sys.argv[2]) if len(sys.argv) > 2 else 200
runs = int(sys.argv[3]) if len(sys.argv) > 3 else 3

def free_port():
    s = socket.socket(); s.bind(("127.0.0.1", 0)); p = s.getsockname()[1]; s.close(); return p

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

def render():
    t = time.monotonic()
    subprocess.run([f"{bindir}/tessera", "submit"] + job, env=env, check=True, stdout=subprocess.DEVNULL)
    return time.monotonic() - t

def open_stream(rcvbuf=None):
    s = socket.socket()
    if rcvbuf: s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    s.connect(("127.0.0.1", http))
    s.sendall(f"GET /api/events HTTP/1.1\r\nHost: 127.0.0.1:{http}\r\n\r\n".encode())
    return s

times = {"none": [], "clients": []}
received = [0]
for r in range(runs):
    times["none"].append(render())
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
        got = 0
        deadline = time.monotonic() + 600
        while time.monotonic() < deadline:
            for k, _ in sel.select(0.1):
                try:
                    n = len(k.fileobj.recv(65536))
                    if n == 0: os._exit(0)
                    got += n
                except (BlockingIOError, ConnectionError): pass
        os._exit(0)
    os.read(rd, 1)
    stalled = open_stream(rcvbuf=4096)
    times["clients"].append(render())
    os.kill(child, 15); os.waitpid(child, 0)
    stalled.close()
    print(f"run {r}: no clients {times['none'][-1]:.2f} s, {nclients}+1 clients {times['clients'][-1]:.2f} s", flush=True)
rss = int([l for l in open(f"/proc/{coord.pid}/status") if l.startswith("VmHWM")][0].split()[1])
for w in workers: w.terminate()
coord.terminate(); coord.wait()
m0, m1 = statistics.median(times["none"]), statistics.median(times["clients"])
print(f"median: no clients {m0:.2f} s, with clients {m1:.2f} s ({100 * (m1 / m0 - 1):+.1f}%); "
      f"coordinator peak RSS {rss} KiB")
