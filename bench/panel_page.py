#!/usr/bin/env python3
"""What the panel's page costs the browser: the share of wall time its renderer's main thread
is busy (Chromium's Performance.getMetrics TaskDuration), per plot span, while a drive streams.

    bench/panel_page.py URL [--label TEXT] [--seconds 10] [--spans 5,60]

Drives Chromium's headless shell (else chromium) through chromedriver, opens URL (a running
`drive-emu run --panel`), waits for the stream, then for each span: selects it, lets it settle
2 s, and measures over --seconds. Prints one line per span. Standard library only.
bench/panel-page.sh runs it inside user-mode Linux against a drive on vcan0.
"""
import argparse
import json
import os
import shutil
import socket
import subprocess
import tempfile
import time
import urllib.error
import urllib.request


def call(method, url, body=None, timeout=600):
    data = json.dumps(body).encode() if body is not None else None
    r = urllib.request.Request(url, data=data, method=method,
                               headers={"Content-Type": "application/json"})
    try:
        v = json.load(urllib.request.urlopen(r, timeout=timeout))
    except urllib.error.HTTPError as e:  # a WebDriver error: say which
        v = json.load(e)
    if isinstance(v.get("value"), dict) and "error" in v["value"]:
        raise RuntimeError(f"{url}: {v['value']['error']}: {v['value'].get('message')}")
    return v["value"]


def browser():
    if os.environ.get("DRIVE_EMU_CHROME"):
        p = os.environ["DRIVE_EMU_CHROME"]
        return p, "chrome-headless-shell" if "headless-shell" in p else "chrome"
    shell = "/usr/lib/chromium/chromium-headless-shell"
    if os.path.exists(shell):
        return shell, "chrome-headless-shell"
    return shutil.which("chromium"), "chrome"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("url")
    ap.add_argument("--label", default="")
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--spans", default="5,60")
    a = ap.parse_args()
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    drv = subprocess.Popen(["chromedriver", f"--port={port}"], stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL)
    base = f"http://127.0.0.1:{port}"
    profile = tempfile.mkdtemp(prefix="panel-page-")
    try:
        t0 = time.monotonic()
        while True:
            try:
                if call("GET", base + "/status", timeout=5)["ready"]:
                    break
            except OSError:
                pass
            if time.monotonic() - t0 > 60:
                raise TimeoutError("chromedriver did not start")
            time.sleep(0.1)
        binary, name = browser()
        sid = call("POST", base + "/session", {"capabilities": {"alwaysMatch": {
            "browserName": name, "goog:chromeOptions": {"binary": binary, "args": [
                "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--no-first-run",
                "--disable-dev-shm-usage", f"--user-data-dir={profile}",
                "--window-size=1600,1500"]}}}})["sessionId"]
        s = f"{base}/session/{sid}"
        call("POST", s + "/url", {"url": a.url})

        def js(script):
            return call("POST", s + "/execute/sync", {"script": script, "args": []})

        def cdp(cmd, params=None):
            return call("POST", s + "/goog/cdp/execute", {"cmd": cmd, "params": params or {}})

        t0 = time.monotonic()
        while not js("const p = panel.plotted(0); return !!(p && p.points > 0)"):
            if time.monotonic() - t0 > 120:
                raise TimeoutError("nothing plotted in 120 s")
            time.sleep(0.5)
        cdp("Performance.enable")

        def busy():
            m = {x["name"]: x["value"] for x in cdp("Performance.getMetrics")["metrics"]}
            # the page's drawings so far (a page before panel.counts(): null, 0 a second)
            d = js("const p = panel.plotted(0), c = panel.counts ? panel.counts() : {}; "
                   "return p && [p.points, c.draws]")
            return m["TaskDuration"], m["ScriptDuration"], time.monotonic(), d

        for span in a.spans.split(","):
            try:
                js(f"const s = document.getElementById('span'); s.value = '{span}'; "
                   "s.dispatchEvent(new Event('change')); return 1")
                time.sleep(2)
                task0, script0, w0, d0 = busy()
                time.sleep(a.seconds)
                task1, script1, w1, d1 = busy()
            except (RuntimeError, OSError) as e:
                print(json.dumps({"label": a.label, "span_s": float(span), "error": str(e)[:200]}),
                      flush=True)
                continue
            print(json.dumps({"label": a.label, "span_s": float(span),
                              "main_thread_busy": round((task1 - task0) / (w1 - w0), 3),
                              "script_busy": round((script1 - script0) / (w1 - w0), 3),
                              "draws_per_s": round(((d1[1] or 0) - (d0[1] or 0)) / (w1 - w0), 1),
                              "points_a_plot": d1[0]}),
                  flush=True)
        call("DELETE", s)
    finally:
        drv.kill()
        shutil.rmtree(profile, ignore_errors=True)


if __name__ == "__main__":
    main()
