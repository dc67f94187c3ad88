"""farmkit.py - what the dashboard benchmarks (dashboard_https.py,
dashboard_stall.py, dashboard_clients.py) share: a free loopback port, and
one job rendered by a worker of its own on a running coordinator."""
import os, socket, subprocess


def free_port():
    """A TCP port free on 127.0.0.1 now."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def render_job(bindir, port, scene, width, tile_size=64, threads=2):
    """Render scene at width x width, 1 spp, on the coordinator at
    127.0.0.1:port with a worker started (and stopped) for it; returns once
    the job is done (tessera submit --wait; raises when it fails)."""
    w = subprocess.Popen([f"{bindir}/tessera-worker", "--connect", f"127.0.0.1:{port}", "--threads", str(threads)],
                         stderr=subprocess.DEVNULL)
    try:
        subprocess.run([f"{bindir}/tessera", "submit", scene, "--width", str(width), "--height", str(width), "--spp",
                        "1", "--tile-size", str(tile_size), "--wait"], check=True, capture_output=True,
                       env=dict(os.environ, TESSERA_COORDINATOR=f"127.0.0.1:{port}"))
    finally:
        w.terminate()
        w.wait(60)
