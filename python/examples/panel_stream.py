#!/usr/bin/env python3
"""Read the live panel's stream of `drive-emu run --panel` (docs/panel.md), python stdlib only.

    drive-emu run --iface vcan0 --node 5 --panel &          # panel on 127.0.0.1:8080
    python panel_stream.py --url http://127.0.0.1:8080 --count 50
    python panel_stream.py --inject '{"set": "backlash_mm", "value": 0.05}'

The stream is server-sent events (`event: TYPE` / `data: JSON` / blank line) at
GET /api/stream; each message's JSON has a "type" equal to the event name: hello (once, the
axes and the controls), samples (25 a second: every axis's new samples as columns, and its
state), stats (0x2100, twice a second), spectrum (with the detector's verdict, once a second
per axis), emcy, injection, recording, lagged. With --token (or a panel started with
--panel-token) the token goes in the Authorization header.

Prints one line per message (or the JSON itself with --json); with --inject, first posts
that write to /api/inject and prints the answer. Exit status 0 when --count messages were
read, 1 on an error reply.
"""
import argparse
import json
import sys
import urllib.error
import urllib.request


def request(url, token, data=None):
    req = urllib.request.Request(url, data=data)
    if data is not None:
        req.add_header("Content-Type", "application/json")
    if token:
        req.add_header("Authorization", "Bearer " + token)
    return urllib.request.urlopen(req, timeout=30)


def events(resp):
    """(event name, parsed JSON) for each server-sent event of `resp`."""
    name, data = "message", []
    for raw in resp:
        line = raw.decode("utf-8").rstrip("\r\n")
        if not line:
            if data:
                yield name, json.loads("\n".join(data))
            name, data = "message", []
        elif line.startswith("event:"):
            name = line[6:].strip()
        elif line.startswith("data:"):
            data.append(line[5:].lstrip(" "))


def describe(kind, m):
    """One line for people."""
    if kind == "hello":
        axes = ", ".join(f"node {a['node_id']} ({a['preset']}, 1 uu = {a['user_unit']})"
                         for a in m["axes"])
        return f"hello: {m['tick_hz']} Hz, {m['samples_per_s']} samples/s per axis: {axes}"
    if kind == "samples":
        parts = []
        for a in m["axes"]:
            s, st = a["samples"], a["state"]
            n = len(s["t_s"])
            pos = s["position_actual_uu"][-1] if n else st["position_actual_uu"]
            parts.append(f"node {a['node_id']} {st['cia402_state']} {st['mode_name']} "
                         f"{n} samples, position {pos} uu, "
                         f"following error {st['following_error_uu']} uu")
        return f"t={m['t_s']:.3f} s " + "; ".join(parts)
    if kind == "spectrum":
        d = m["detector"]
        peak = m["peak"]["frequency_hz"] if m["peak"] else "-"
        return (f"t={m['t_s']:.3f} s node {m['node_id']} spectrum peak {peak} Hz, "
                f"detector {d['verdict']}")
    if kind == "stats":
        return (f"t={m['t_s']:.3f} s loop: {m['ticks']} ticks, {m['overruns']} overruns, "
                f"lateness p99 {m['lateness_p99_us']} us, {m['clients']} clients")
    if kind == "emcy":
        return (f"t={m['t_s']:.3f} s node {m['node_id']} EMCY {m['code']} "
                f"{'raised' if m['raised'] else 'cleared'} ({m['meaning']})")
    if kind == "injection":
        return f"t={m['t_s']:.3f} s node {m['node_id']} injected: {m['event']}"
    return f"{kind}: {json.dumps(m)}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--url", default="http://127.0.0.1:8080", help="the panel's address")
    ap.add_argument("--token", help="the panel's --panel-token")
    ap.add_argument("--count", type=int, default=20, help="messages to read, then stop")
    ap.add_argument("--json", action="store_true", help="print each message's JSON")
    ap.add_argument("--inject", help="a write to post first, e.g. "
                    "'{\"set\": \"backlash_mm\", \"value\": 0.05}'")
    args = ap.parse_args()
    base = args.url.rstrip("/")
    if args.inject:
        try:
            with request(base + "/api/inject", args.token, args.inject.encode()) as r:
                print("inject:", r.read().decode())
        except urllib.error.HTTPError as e:
            print(f"inject refused ({e.code}): {e.read().decode()}", file=sys.stderr)
            return 1
    try:
        resp = request(base + "/api/stream", args.token)
    except urllib.error.HTTPError as e:
        print(f"stream refused ({e.code}): {e.read().decode()}", file=sys.stderr)
        return 1
    with resp:
        for i, (kind, m) in enumerate(events(resp)):
            if m.get("type") != kind:
                print(f"message type {m.get('type')!r} under event {kind!r}", file=sys.stderr)
                return 1
            print(json.dumps(m) if args.json else describe(kind, m), flush=True)
            if i + 1 >= args.count:
                return 0
    print("the stream ended", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
