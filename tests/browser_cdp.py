#!/usr/bin/env python3
"""browser_cdp.py - Debian's headless Chromium driven over the DevTools
protocol (--remote-debugging-pipe: no extra library), for the dashboard's
browser tests (browser_dashboard.py, browser_users.py, browser_https.py): pages, JavaScript
evaluated in them, bounded waits, screenshots. fail() prints "FAIL: ..."
and exits 1."""
import base64, json, os, select, subprocess, sys, time


def fail(msg):
    print("FAIL:", msg, flush=True)
    sys.exit(1)


class Chromium:
    """One headless Chromium; DevTools messages are NUL-separated JSON on
    fds 3 (to it) and 4 (from it)."""

    def __init__(self, profile, extra=()):
        to_r, self.to_w = os.pipe()
        self.from_r, from_w = os.pipe()

        def fds():
            os.dup2(to_r, 3)
            os.dup2(from_w, 4)
        self.p = subprocess.Popen(["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                                   "--remote-debugging-pipe", f"--user-data-dir={profile}", *extra, "about:blank"],
                                  pass_fds=(3, 4), preexec_fn=fds, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        os.close(to_r)
        os.close(from_w)
        self.buf, self.next_id = b"", 0

    def call(self, method, params=None, session=None, timeout=60):
        self.next_id += 1
        m = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            m["sessionId"] = session
        os.write(self.to_w, json.dumps(m).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            while b"\0" in self.buf:
                msg, self.buf = self.buf.split(b"\0", 1)
                r = json.loads(msg)
                if r.get("id") == self.next_id:
                    if "error" in r and method == "Runtime.evaluate" and \
                            any(w in str(r["error"]) for w in ("navigated or closed", "context was destroyed")):
                        raise Navigated(str(r["error"]))
                    if "error" in r:
                        fail(f"{method}: {r['error']}")
                    return r.get("result", {})
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.from_r], [], [], left)[0]:
                fail(f"chromium did not answer {method} within {timeout} s")
            data = os.read(self.from_r, 1 << 20)
            if not data:
                fail("chromium exited")
            self.buf += data

    def page(self, url, width=900):
        tid = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        sid = self.call("Target.attachToTarget", {"targetId": tid, "flatten": True})["sessionId"]
        self.call("Emulation.setDeviceMetricsOverride", {"width": width, "height": 700, "deviceScaleFactor": 1,
                                                          "mobile": False}, sid)
        self.call("Page.navigate", {"url": url}, sid)
        return Page(self, sid)

    def close(self):
        self.p.kill()
        self.p.wait()


class Navigated(Exception):
    """An evaluation the page's own navigation (a form post, a link) cut
    short."""


class Page:
    def __init__(self, chromium, sid):
        self.c, self.sid = chromium, sid

    def js(self, expr):
        """The expression's value; None when the page navigated away while
        it ran (callers poll, or wait for what the navigation brings)."""
        try:
            r = self.c.call("Runtime.evaluate", {"expression": expr, "returnByValue": True, "awaitPromise": True},
                            self.sid)
        except Navigated:
            return None
        return r.get("result", {}).get("value")

    def wait(self, expr, what, timeout=90):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            v = self.js(expr)
            if v:
                return v
            time.sleep(0.1)
        fail(f"{what}: not within {timeout} s (page {self.js('location.href')}: "
             f"{str(self.js('document.body && document.body.innerText'))[:400]!r})")

    def screenshot(self, path):
        data = self.c.call("Page.captureScreenshot", {"format": "png"}, self.sid)["data"]
        with open(path, "wb") as f:
            f.write(base64.b64decode(data))
