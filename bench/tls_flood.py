#!/usr/bin/env python3
"""tls_flood.py - a flood of TLS handshakes on the HTTPS dashboard while a
job renders: does the coordinator's loop (which runs the handshakes) keep
the farm going?

Starts a coordinator with --http-cert/--http-key (a self-signed P-256
certificate) and one worker, then FLOODERS processes that open a TLS
connection, finish the handshake and close it, as fast as they can, for
SECONDS, while `tessera submit --wait` renders cornell-small at 128x128x128.
Prints the job's time, the handshakes made, the coordinator's CPU, its
longest loop iteration (wall and CPU, from status --json) and whether any
worker was found silent. Usage: bench/tls_flood.py BUILD/bin FLOODERS SECONDS
(FLOODERS 0: the same job undisturbed)."""
import json, os, socket, ssl, subprocess, sys, tempfile, time, multiprocessing
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from farmkit import free_port
bindir, nflood, secs = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
d = tempfile.mkdtemp(prefix="flood-")
subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
                "-keyout", f"{d}/key.pem", "-out", f"{d}/cert.pem", "-days", "2", "-subj", "/CN=b",
                "-addext", "subjectAltName=IP:127.0.0.1"], check=True, capture_output=True)
port, web = free_port(), free_port()
c = subprocess.Popen([f"{bindir}/tessera-coordinator", "--listen", f"127.0.0.1:{port}", "--data-dir", f"{d}/data",
                      "--http", f"127.0.0.1:{web}", "--http-cert", f"{d}/cert.pem", "--http-key", f"{d}/key.pem"],
                     stderr=open(f"{d}/coord.log", "w"))
time.sleep(0.5)
w = subprocess.Popen([f"{bindir}/tessera-worker", "--connect", f"127.0.0.1:{port}", "--threads", "1"],
                     stderr=open(f"{d}/worker.log", "w"))
time.sleep(0.5)
env = dict(os.environ, TESSERA_COORDINATOR=f"127.0.0.1:{port}")

def flood(stop_at, q):
    ctx = ssl.create_default_context(cafile=f"{d}/cert.pem")
    n = 0
    while time.time() < stop_at:
        try:
            s = socket.create_connection(("127.0.0.1", web), 2)
            t = ctx.wrap_socket(s, server_hostname="127.0.0.1")
            t.close(); n += 1
        except Exception:
            pass
    q.put(n)

def status():
    out = subprocess.run([f"{bindir}/tessera", "status", "--json"], env=env, capture_output=True, text=True).stdout
    return json.loads(out)

t0 = time.time()
q = multiprocessing.Queue()
ps = [multiprocessing.Process(target=flood, args=(t0 + secs, q)) for _ in range(nflood)]
for p in ps: p.start()
r = subprocess.run([f"{bindir}/tessera", "submit", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "scenes", "cornell-small.json"), "--width", "128",
                    "--height", "128", "--spp", "128", "--wait", "-q", "-o", f"{d}/x.pfm"], env=env,
                   capture_output=True, text=True)
job_s = time.time() - t0
for p in ps: p.join()
hs = sum(q.get() for _ in ps)
st = status()
keys = {k: st.get(k) for k in st if "stall" in k}
f = open(f"/proc/{c.pid}/stat").read().rsplit(")", 1)[1].split()
cpu = (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")
print(f"flooders {nflood}: job {job_s:.2f} s ({r.returncode}), handshakes {hs} in {secs} s, coordinator CPU {cpu:.2f} s, {keys}")
print(open(f"{d}/coord.log").read()[-600:] if "silent" in open(f"{d}/coord.log").read() else "no worker silent")
c.terminate(); w.terminate(); c.wait(); w.wait()
