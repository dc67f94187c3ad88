#!/usr/bin/env python3
"""browser_https.py - the dashboard over HTTPS (--http-cert, --http-key) in
Debian's headless Chromium (browser_cdp.py), against a coordinator started
by tests/test_http.c with one finished job. Chromium trusts the served
certificate by its public key's hash only (--ignore-certificate-errors-spki-list),
so a different certificate would fail the page.

  login:   https://.../ sends the browser to the login form; the token signs
           it in: the Secure session cookie is kept and sent over HTTPS
  jobs:    the job list loads (the cookie works for the page's fetches)
  job:     the finished job's page shows its image, fetched over HTTPS

Every wait is bounded. Prints "ok: ..." per check; exits 1 with "FAIL: ..."
on the first failure. Usage: browser_https.py HTTPS_PORT TOKEN SPKI_SHA256
PROFILE_DIR"""
import json, sys

from browser_cdp import Chromium, fail

port, token, spki, profile = sys.argv[1:5]
base = f"https://127.0.0.1:{port}"
chromium = Chromium(profile, [f"--ignore-certificate-errors-spki-list={spki}"])
try:
    jobs = chromium.page(base + "/", 1280)
    jobs.wait("location.protocol === 'https:' && location.pathname === '/login' &&"
              " !!document.querySelector('input[name=token]')", "the login form over HTTPS")
    jobs.js(f"document.querySelector('input[name=token]').value = {json.dumps(token)};"
            " document.querySelector('form').submit(); true")
    jobs.wait("location.pathname === '/' && !!document.querySelector(\"#jobs a[href='/job/1']\")",
              "the job list after signing in")
    print("ok: signed in over HTTPS; the job list loads with the Secure cookie", flush=True)
    job = jobs.c.page(base + "/job/1")
    job.wait("/done/.test((document.querySelector('#state') || {}).textContent || '') &&"
             " !!document.querySelector('#img').getAttribute('src') && document.querySelector('#img').complete &&"
             " document.querySelector('#img').naturalWidth > 0", "job 1's page shows its image")
    print("ok: the job page shows the image fetched over HTTPS", flush=True)
finally:
    chromium.close()
print("all HTTPS browser checks passed", flush=True)
