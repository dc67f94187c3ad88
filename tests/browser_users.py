#!/usr/bin/env python3
"""browser_users.py - the dashboard signed in with a user's own token
(--client-tokens), in Debian's headless Chromium (browser_cdp.py), against a
coordinator started by tests/test_http.c with two queued jobs: job 1 of
USER, job 2 of OTHER.

  header:  the page says who signed in
  jobs:    Cancel and the priority field for the user's job only
  job:     another user's job page shows its state and whose it is, no image
           and no downloads; the user's own job page shows its image
  cancel:  the user's Cancel button cancels their job

Every wait is bounded. Prints "ok: ..." per check; exits 1 with "FAIL: ..."
on the first failure. Usage: browser_users.py HTTP_PORT TOKEN USER OTHER
PROFILE_DIR"""
import json, sys

from browser_cdp import Chromium, fail

port, token, user, other, profile = sys.argv[1:6]
base = f"http://127.0.0.1:{port}"
chromium = Chromium(profile)
try:
    jobs = chromium.page(base + "/", 1280)
    jobs.wait("location.pathname === '/login' && !!document.querySelector('input[name=token]')", "the login form")
    jobs.js(f"document.querySelector('input[name=token]').value = {json.dumps(token)};"
            " document.querySelector('form').submit(); true")
    jobs.wait(f"document.querySelector('#who') && document.querySelector('#who').textContent === "
              f"{json.dumps('signed in as ' + user)}", f"the header says {user} signed in")
    print(f"ok: the header says 'signed in as {user}'", flush=True)
    jobs.wait("!!document.querySelector(\"#jobs a[href='/job/2']\") && !!document.querySelector(\"[data-cancel='1']\")",
              "both jobs listed, job 1 with a Cancel button")
    rights = jobs.js("[!!document.querySelector(\"[data-cancel='1']\"), !!document.querySelector('#pri-1'),"
                     " !!document.querySelector(\"[data-cancel='2']\"), !!document.querySelector('#pri-2')]")
    if rights != [True, True, False, False]:
        fail(f"Cancel and priority for job 1 only, got [cancel 1, priority 1, cancel 2, priority 2] = {rights}")
    print(f"ok: Cancel and priority for {user}'s job 1, none for {other}'s job 2", flush=True)
    theirs = chromium.page(base + "/job/2")
    theirs.wait(f"/only its owner, {other}, and the admin see its pixels/.test("
                "(document.querySelector('#state') || {}).textContent || '')", f"job 2's page says it is {other}'s")
    shown = theirs.js("[getComputedStyle(document.querySelector('#view')).display, document.querySelector('#dl').hidden,"
                      " document.querySelector('#img').getAttribute('src')]")
    if shown != ["none", True, None]:
        fail(f"job 2's page shows its image or downloads: [view display, downloads hidden, img src] = {shown}")
    print(f"ok: {other}'s job page shows its state, no image and no downloads", flush=True)
    mine = chromium.page(base + "/job/1")
    mine.wait("/queued$/.test((document.querySelector('#state') || {}).textContent || '') &&"
              " getComputedStyle(document.querySelector('#view')).display !== 'none' &&"
              " !!document.querySelector('#img').getAttribute('src')", f"{user}'s job page shows its image")
    print(f"ok: {user}'s own job page shows its image", flush=True)
    jobs.js("document.querySelector(\"[data-cancel='1']\").click(); true")
    jobs.wait("(() => { const a = document.querySelector(\"#jobs a[href='/job/1']\");"
              " return a && a.closest('tr').querySelectorAll('td')[2].textContent.startsWith('cancelled'); })()",
              "job 1 shown cancelled after the click")
    print(f"ok: {user}'s Cancel button cancelled job 1", flush=True)
finally:
    chromium.close()
print("all user checks passed", flush=True)
