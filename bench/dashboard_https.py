#!/usr/bin/env python3
"""dashboard_https.py - what HTTPS (--http-cert, --http-key) costs the
dashboard, against plain HTTP on the same coordinator build.

Makes a self-signed P-256 certificate (openssl req), renders one job with a
worker (WIDTH x WIDTH, 1 spp) on a coordinator, then, ROUNDS times
alternating plain and HTTPS coordinators on the same data dir:
  - N sequential GET /healthz, each on a new connection (so each HTTPS one
    pays a full handshake): requests/s and the coordinator's CPU per
    request (from /proc, so other load does not count);
  - the finished job's EXR downloaded 3 times: MB/s and the coordinator's
    CPU per MB.
Prints each round and the medians. Usage: bench/dashboard_https.py
BUILD/bin [N] [ROUNDS] [WIDTH]"""
import http.client, os, socket, ssl, statistics, subprocess, sys, tempfile, time

from farmkit import free_port, render_job

bindir = sys.argv[1]
n = int(sys.argv[2]) if len(sys.argv) > 2 else 300
rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 3
width = int(sys.argv[4]) if len(sys.argv) > 4 else 2048
tick = os.sysconf("SC_CLK_TCK")


def cpu(pid):
    f = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / tick


d = tempfile.mkdtemp(prefix="tessera-https-bench-")
subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
                "-keyout", f"{d}/key.pem", "-out", f"{d}/cert.pem", "-days", "2", "-subj", "/CN=bench",
                "-addext", "subjectAltName=IP:127.0.0.1"], check=True, capture_output=True)
port = free_port()


def start(https):
    web = free_port()
    args = [f"{bindir}/tessera-coordinator", "--listen", f"127.0.0.1:{port}", "--data-dir", f"{d}/data",
            "--http", f"127.0.0.1:{web}"]
    if https:
        args += ["--http-cert", f"{d}/cert.pem", "--http-key", f"{d}/key.pem"]
    p = subprocess.Popen(args, stderr=open(f"{d}/coord.log", "a"))
    for _ in range(100):
        try:
            socket.create_connection(("127.0.0.1", web), 0.1).close()
            return p, web
        except OSError:
            time.sleep(0.05)
    sys.exit("coordinator did not start; log " + f"{d}/coord.log")


def stop(p):
    p.terminate()
    p.wait(60)


ctx = ssl.create_default_context(cafile=f"{d}/cert.pem")


def get(https, web, path):
    c = (http.client.HTTPSConnection("127.0.0.1", web, context=ctx, timeout=60) if https
         else http.client.HTTPConnection("127.0.0.1", web, timeout=60))
    c.request("GET", path)
    r = c.getresponse()
    body = r.read()
    c.close()
    if r.status != 200:
        sys.exit(f"GET {path}: {r.status} {body[:200]!r}")
    return body


# the job whose image is downloaded
p, _ = start(False)
render_job(bindir, port, "scenes/cornell-box.json", width)
stop(p)

res = {False: [], True: []}
for r in range(rounds):
    for https in ((False, True) if r % 2 == 0 else (True, False)):
        p, web = start(https)
        get(https, web, "/healthz")
        c0, t0 = cpu(p.pid), time.monotonic()
        for _ in range(n):
            get(https, web, "/healthz")
        t1, c1 = time.monotonic(), cpu(p.pid)
        size = 0
        for _ in range(3):
            size += len(get(https, web, "/api/jobs/1/image.exr"))
        t2, c2 = time.monotonic(), cpu(p.pid)
        stop(p)
        mb = size / 1e6
        row = (n / (t1 - t0), (c1 - c0) / n * 1e3, mb / (t2 - t1), (c2 - c1) / mb * 1e3)
        res[https].append(row)
        print(f"round {r + 1} {'https' if https else 'http '}: {row[0]:7.0f} requests/s, {row[1]:.3f} ms CPU per "
              f"request; EXR {mb / 3:.1f} MB x 3: {row[2]:6.0f} MB/s, {row[3]:.2f} ms CPU per MB", flush=True)
for https in (False, True):
    m = [statistics.median(x[i] for x in res[https]) for i in range(4)]
    print(f"median {'https' if https else 'http '}: {m[0]:7.0f} requests/s, {m[1]:.3f} ms CPU per request; "
          f"EXR {m[2]:6.0f} MB/s, {m[3]:.2f} ms CPU per MB")
print(f"load average {os.getloadavg()[0]:.2f}; files in {d}")
