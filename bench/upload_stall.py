#!/usr/bin/env python3
"""upload_stall.py - the coordinator's loop while it takes in the largest
scene it accepts (issue 20): a scene whose JSON is just under the parse cap
(UPLOAD_JSON_MAX, 16 MiB) with a mesh that brings the bundle just under
--max-upload (64 MiB), submitted with `tessera submit` while a worker is
connected and another client asks `status` every 20 ms. Prints per round
the longest loop iteration (wall and CPU, the coordinator's own figures),
the slowest status answer, and whether the worker was ever found silent.

    bench/upload_stall.py [ROUNDS] [--json-mib 15] [--mesh-mib 46]
"""
import json, os, socket, struct, subprocess, sys, tempfile, threading, time

import wire

BIN = os.environ.get("BIN", "build/release/bin")


def frame_read(s):
    return wire.read_frame(s)


def frame_send(s, obj):
    s.sendall(wire.json_frame(obj))


def client(port, build):
    s = socket.create_connection(("127.0.0.1", port))
    frame_read(s)  # challenge
    frame_send(s, {"type": "hello", "role": "client", "protocol": 1, "build": build, "name": "bench", "threads": 1})
    _, w = frame_read(s)
    assert b"welcome" in w, w
    return s


def status(s):
    frame_send(s, {"type": "status"})
    _, b = frame_read(s)
    return json.loads(b)


def make_scene(d, json_mib, mesh_mib):
    mats, shapes, i = {}, [], 0
    size = 0
    while size < json_mib * 1048576:
        mats["m%d" % i] = {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}
        shapes.append({"type": "sphere", "center": [i % 97, (i // 97) % 97, 50 + i // 9409], "radius": 0.25,
                       "material": "m%d" % i})
        size += 150
        i += 1
    shapes.append({"type": "mesh", "file": "big.obj", "material": "m0"})
    scene = {"render": {"width": 32, "height": 32, "spp": 1},
             "camera": {"type": "perspective", "position": [48, 48, -100], "look_at": [48, 48, 0], "fov": 40},
             "materials": mats, "shapes": shapes}
    text = json.dumps(scene)
    while len(text) > json_mib * 1048576:  # stay under the parse cap
        scene["shapes"].pop(0)
        text = json.dumps(scene)
    open(os.path.join(d, "scene.json"), "w").write(text)
    with open(os.path.join(d, "big.obj"), "w") as f:
        n, k = 0, 0
        while n < mesh_mib * 1048576:
            x, y = k % 1000, k // 1000
            line = "v %d %d 10\nv %d.5 %d 10\nv %d %d.5 10\nf %d %d %d\n" % (x, y, x, y, x, y, 3 * k + 1, 3 * k + 2,
                                                                            3 * k + 3)
            f.write(line)
            n += len(line)
            k += 1
    return len(text), os.path.getsize(os.path.join(d, "big.obj"))


def one_round(r, json_mib, mesh_mib):
    d = tempfile.mkdtemp(prefix="tessera-upload-stall.")
    jb, mb = make_scene(d, json_mib, mesh_mib)
    log = open(os.path.join(d, "coord.log"), "w")
    coord = subprocess.Popen([BIN + "/tessera-coordinator", "--listen", "127.0.0.1:0", "--data-dir", d + "/data"],
                             stdout=log, stderr=subprocess.STDOUT)
    port = None
    for _ in range(400):
        t = open(os.path.join(d, "coord.log")).read()
        if "listening on" in t:
            port = int(t.split("listening on 127.0.0.1:")[1].split(",")[0])
            break
        time.sleep(0.05)
    perf = None
    if os.environ.get("STRACE"):  # the loop thread's slow system calls
        perf = subprocess.Popen(["strace", "-T", "-o", os.environ["STRACE"], "-p", str(coord.pid)],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    elif os.environ.get("PERF"):  # the loop thread only (its tid is the pid)
        perf = subprocess.Popen(["perf", "record", "-g", "-t", str(coord.pid), "-o", os.environ["PERF"]],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    build = subprocess.run([BIN + "/tessera", "version"], capture_output=True, text=True).stdout.split("build ")[1].split(",")[0]
    worker = subprocess.Popen([BIN + "/tessera-worker", "--connect", "127.0.0.1:%d" % port, "--threads", "1",
                               "--name", "w1"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    st = client(port, build)
    for _ in range(200):
        if status(st)["workers"] >= 1:
            break
        time.sleep(0.05)
    lat, stop = [], threading.Event()

    def poll():
        while not stop.is_set():
            t0 = time.monotonic()
            status(st)
            lat.append(time.monotonic() - t0)
            time.sleep(0.02)

    th = threading.Thread(target=poll)
    th.start()
    env = dict(os.environ, TESSERA_COORDINATOR="127.0.0.1:%d" % port)
    t0 = time.monotonic()
    sub = subprocess.run([BIN + "/tessera", "submit", os.path.join(d, "scene.json")], env=env, capture_output=True,
                         text=True)
    t_submit = time.monotonic() - t0
    time.sleep(1.0)
    stop.set()
    th.join()
    a = status(st)
    st.close()
    if perf:
        perf.send_signal(2)
        perf.wait()
    worker.terminate()
    worker.wait()
    coord.terminate()
    coord.wait()
    silent = open(os.path.join(d, "coord.log")).read().count("silent for")
    load = open("/proc/loadavg").read().split()[0]
    print("round %d: JSON %.1f MiB + mesh %.1f MiB, submit %s in %.2f s; loop: longest %.1f ms wall, %.1f ms CPU; "
          "%d status answers, slowest %.1f ms, median %.1f ms; worker silent %d times; load %s" %
          (r, jb / 1048576, mb / 1048576, "ok" if sub.returncode == 0 else "FAILED: " + sub.stderr.strip(), t_submit,
           a["longest_stall_ms"], a["longest_stall_cpu_ms"], len(lat), max(lat) * 1e3,
           sorted(lat)[len(lat) // 2] * 1e3, silent, load), flush=True)
    subprocess.run(["rm", "-rf", d])


if __name__ == "__main__":
    args = sys.argv[1:]
    rounds = int(args[0]) if args and not args[0].startswith("-") else 3
    jm = float(args[args.index("--json-mib") + 1]) if "--json-mib" in args else 15
    mm = float(args[args.index("--mesh-mib") + 1]) if "--mesh-mib" in args else 46
    for r in range(1, rounds + 1):
        one_round(r, jm, mm)
