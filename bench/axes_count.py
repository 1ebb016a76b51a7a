"""Count, in a `candump -L` capture, the synchronous TPDOs (TPDO2/3/4: 0x280/0x380/0x480 +
node) each node sent per SYNC, and print them with the drive's own exit statistics.

    python3 bench/axes_count.py CAPTURE.log STATS.json AXES LABEL

A frame is lost when a node sent fewer TPDOs of a kind than there were SYNCs; out of order
when the n-th TPDO of a kind came before the n-th SYNC. STATS.json is `drive-emu run --json`'s
stdout (the `--ready` line, then the statistics).
"""
import json
import sys

cap, stats_path, axes, label = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
KINDS = (0x280, 0x380, 0x480)
counts = {(k, n): 0 for k in KINDS for n in range(1, axes + 1)}
syncs, disorder, drops_seen, t_first, t_last = 0, 0, [], None, None
with open(cap) as f:
    for line in f:
        if "DROP" in line.upper():
            drops_seen.append(line.strip())
            continue
        parts = line.split()
        if len(parts) < 3 or "#" not in parts[2]:
            continue
        cob = int(parts[2].split("#")[0], 16)
        if cob == 0x080:
            syncs += 1
            t = float(parts[0].strip("()"))
            t_first = t if t_first is None else t_first
            t_last = t
            continue
        base, node = cob & ~0x7F, cob & 0x7F
        if base in KINDS and 1 <= node <= axes:
            counts[(base, node)] += 1
            if counts[(base, node)] > syncs:
                disorder += 1
lost = sum(max(0, syncs - c) for c in counts.values())
extra = sum(max(0, c - syncs) for c in counts.values())
short_nodes = sorted({n for (k, n), c in counts.items() if c < syncs})
text, docs, i = open(stats_path).read(), [], 0
while (i := text.find("{", i)) >= 0:  # the --ready line, then the statistics
    doc, i = json.JSONDecoder().raw_decode(text, i)
    docs.append(doc)
s = next(d["stats"] for d in docs if "stats" in d)
rate = (syncs - 1) / (t_last - t_first) if syncs > 1 and t_last > t_first else 0.0
print(
    f"{label}: {syncs} SYNCs ({rate:.0f}/s on the bus), {axes} axes x 3 TPDOs: "
    f"lost {lost}, extra {extra}, out of order {disorder}"
    + (f" (nodes short: {short_nodes[:8]}{'...' if len(short_nodes) > 8 else ''})" if lost else "")
)
print(
    f"{label}: drive: tx dropped {s['tx_dropped']}, tx full waits {s['tx_full_waits']}, "
    f"rx overflows {s['rx_overflows']}, skipped ticks {s['skipped_ticks']}, "
    f"lateness p50/p99/max {s['lateness_p50_us']}/{s['lateness_p99_us']}/{s['lateness_max_us']} us, "
    f"work p50/p99/max {s['work_p50_us']}/{s['work_p99_us']}/{s['work_max_us']} us, "
    f"{['free-running', 'acquiring SYNC', 'SYNC-locked'][s['sync_lock_state']]}"
)
if drops_seen:
    total = max(int(d.split("total drops")[1].strip(" )")) for d in drops_seen)
    print(f"{label}: the capture itself dropped {total} frames (candump fell behind): the count above is not the drive's")
