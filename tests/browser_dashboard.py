#!/usr/bin/env python3
"""browser_dashboard.py - drive the dashboard in Debian's headless Chromium
over the DevTools protocol (--remote-debugging-pipe: no extra library),
against a running tessera-coordinator with a worker and a token (started
by tests/test_http.c, which also checks the screenshot's pixels).

  login:    "/" sends the browser to the login form; the token logs it in
  jobs:     a submitted job appears in the table and its progress rises
  job:      while it renders, tiles are outlined on the live preview and the
            event log shows tiles handed to the worker; when done, EXR and
            PNG downloads work; a screenshot of the page is written (and
            SHOT-live.png while it rendered, SHOT-jobs.png of the table)
  cancel:   the Cancel button of a running job cancels it
  priority: the priority field and Set change a queued job's priority
  workers:  the worker is listed and the throughput plot is drawn

Every wait is bounded. Prints "ok: ..." per check; exits 1 with "FAIL: ..."
on the first failure. Usage: browser_dashboard.py HTTP_PORT TOKEN TESSERA
COORDINATOR TOKEN_FILE SCREENSHOT PROFILE_DIR"""
import json, os, subprocess, sys, time

from browser_cdp import Chromium, fail

port, token, tessera, coordinator, token_file, shot, profile = sys.argv[1:8]
# While this file exists the worker keeps its 17th tile (TESSERA_TEST_HOLD_FILE):
# job 1 stays running with tiles outlined until the page has been seen so.
hold = sys.argv[8] if len(sys.argv) > 8 else None


def release():
    if hold and os.path.exists(hold):
        os.unlink(hold)
base = f"http://127.0.0.1:{port}"
env = dict(os.environ, TESSERA_COORDINATOR=coordinator, TESSERA_TOKEN_FILE=token_file)


def submit(*args):
    r = subprocess.run([tessera, "submit", *args], env=env, capture_output=True, text=True, timeout=120)
    if r.returncode:
        fail(f"tessera submit {' '.join(args)}: {r.stderr}")
    return int(r.stdout.split()[-1])


def status(job):
    r = subprocess.run([tessera, "status", str(job), "--json"], env=env, capture_output=True, text=True, timeout=60)
    if r.returncode:
        fail(f"tessera status {job}: {r.stderr}")
    return json.loads(r.stdout)["jobs"][0]


ROW = "((id) => { const a = document.querySelector(\"#jobs a[href='/job/\" + id + \"']\"); if (!a) return null;" \
      " const td = a.closest('tr').querySelectorAll('td'); return [td[2].textContent, parseInt(td[3].textContent)]; })"

chromium = Chromium(profile)
try:
    jobs = chromium.page(base + "/", 1280)
    jobs.wait("location.pathname === '/login' && !!document.querySelector('input[name=token]')",
              "the jobs page sends a browser without the token to the login form")
    print("ok: / without the token shows the login form", flush=True)
    jobs.js(f"document.querySelector('input[name=token]').value = {json.dumps(token)};"
            " document.querySelector('form').submit(); true")
    jobs.wait("location.pathname === '/' && !!document.querySelector('#jobs')", "the token logs in")
    print("ok: the token logs in (session cookie)", flush=True)

    job_page = chromium.page(base + "/job/1")  # open before the job exists: it picks it up
    if hold:
        open(hold, "w").close()
    job = submit("scenes/cornell-box.json", "--width", "128", "--height", "128", "--spp", "64", "--tile-size", "16")
    if job != 1:
        fail(f"expected job 1, got {job}")
    seen, outlined = [], 0
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        row = jobs.js(ROW + "(1)")
        if row and (not seen or row[1] != seen[-1]):
            seen.append(row[1])
        if job_page.js("document.querySelector('#state') && / running$/.test(document.querySelector('#state').textContent)"):
            before = outlined
            outlined = max(outlined, job_page.js(
                "(() => { const c = document.querySelector('#ov'); if (!c || !c.width) return 0;"
                " const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; let n = 0;"
                " for (let i = 0; i < d.length; i += 4) n += d[i] < 60 && d[i + 1] > 150 && d[i + 2] > 200;"
                " return n; })()") or 0)
            if outlined and not before:  # the live preview with its outlined tiles, for the docs
                for _ in range(20):  # not while the newest preview is being decoded
                    if job_page.js("document.querySelector('#img').complete"):
                        break
                    time.sleep(0.05)
                job_page.screenshot(shot.replace(".png", "-live.png"))
            # Let the held tile go once both pages have seen the job running:
            # the outlines here, and a progress below 100% on the jobs page
            # (releasing on the outlines alone, the job could finish before
            # the jobs page first listed it: seen [100], a failure in CI).
            if outlined and seen and seen[-1] < 100:
                release()
        if time.monotonic() > deadline - 150:  # 30 s held without an outline seen: let it finish (and fail below)
            release()
        if row and row[0].startswith("done"):
            break
        time.sleep(0.2)
    if not seen or seen[-1] != 100 or len(seen) < 2 or seen != sorted(seen):
        fail(f"job 1's progress on the jobs page did not rise to 100%: {seen}")
    print(f"ok: job 1 appeared on the jobs page; progress rose {seen}", flush=True)
    if outlined <= 0:
        fail("no tile was outlined on the job page while job 1 rendered")
    print(f"ok: tiles outlined while rendering ({outlined} outline pixels at most)", flush=True)
    job_page.wait("/ done$/.test(document.querySelector('#state').textContent) && !document.querySelector('#dl').hidden",
                  "the job page shows job 1 done with its downloads")
    log = job_page.wait("(() => { const t = document.querySelector('#log').textContent;"
                        " return /handed to webworker/.test(t) && /job done/.test(t) && t; })()",
                        "the job page's event log shows the tiles and the end")
    print(f"ok: the event log on the page ({log.count(chr(10)) + 1} lines)", flush=True)
    exr = job_page.js("fetch(document.querySelector('#dlexr').href).then((r) => r.arrayBuffer())"
                      ".then((b) => [b.byteLength, ...new Uint8Array(b).slice(0, 4)])")
    png = job_page.js("fetch(document.querySelector('#dlpng').href).then((r) => r.arrayBuffer())"
                      ".then((b) => [b.byteLength, ...new Uint8Array(b).slice(0, 4)])")
    if not exr or exr[1:] != [0x76, 0x2F, 0x31, 0x01] or not png or png[1:] != [0x89, 0x50, 0x4E, 0x47]:
        fail(f"downloads: EXR {exr}, PNG {png}")
    print(f"ok: downloads: EXR {exr[0]} bytes, PNG {png[0]} bytes", flush=True)
    job_page.wait("document.querySelector('#img').complete && document.querySelector('#img').naturalWidth === 128",
                  "the preview image loads")
    time.sleep(0.5)
    job_page.screenshot(shot)
    print(f"ok: screenshot {shot}", flush=True)

    long_job = ["scenes/cornell-box.json", "--width", "256", "--height", "256", "--spp", "4096", "--tile-size", "32"]
    job = submit(*long_job)
    jobs.wait(f"!!document.querySelector(\"[data-cancel='{job}']\")", f"a Cancel button for job {job}")
    jobs.js(f"document.querySelector(\"[data-cancel='{job}']\").click(); true")
    jobs.wait(f"(({ROW})({job}) || [''])[0].startsWith('cancelled')", f"job {job} shown cancelled after the click")
    if status(job)["state"] != "cancelled":
        fail(f"job {job} is {status(job)['state']} on the coordinator after Cancel")
    print(f"ok: the Cancel button cancelled job {job}", flush=True)

    job = submit(*long_job)
    jobs.wait(f"!!document.querySelector('#pri-{job}')", f"a priority field for job {job}")
    jobs.js(f"document.querySelector('#pri-{job}').value = '7';"
            f" document.querySelector(\"[data-priority='{job}']\").click(); true")
    deadline = time.monotonic() + 60
    while status(job)["priority"] != 7:
        if time.monotonic() > deadline:
            fail(f"job {job}'s priority is {status(job)['priority']} after Set 7")
        time.sleep(0.2)
    print(f"ok: the priority field set job {job}'s priority to 7", flush=True)
    jobs.wait(f"document.querySelector('#pri-{job}') && document.querySelector('#pri-{job}').value === '7'",
              "the jobs table shows the new priority")
    jobs.screenshot(shot.replace(".png", "-jobs.png"))
    subprocess.run([tessera, "cancel", str(job)], env=env, capture_output=True, timeout=60)

    workers = chromium.page(base + "/workers")
    workers.wait("/webworker/.test(document.querySelector('#ws').textContent)", "the workers page lists webworker")
    plotted = workers.wait("(() => { const d = document.querySelector('#plot').getContext('2d')"
                           ".getImageData(0, 0, 600, 120).data; let n = 0;"
                           " for (let i = 0; i < d.length; i += 4) n += d[i + 1] > 120 && d[i] < 120; return n; })()",
                           "the workers page plots the throughput", 30)
    print(f"ok: the workers page lists the worker and plots its throughput ({plotted} plot pixels)", flush=True)
finally:
    release()
    chromium.close()
print("all browser checks passed", flush=True)
