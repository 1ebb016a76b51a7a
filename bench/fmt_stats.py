"""Format loop_bench's JSON line or `drive-emu run --json`'s statistics:
`fmt_stats.py lateness` or `fmt_stats.py axes`."""
import json
import sys

d = json.load(sys.stdin)
s = d["stats"]
if sys.argv[1] == "lateness":
    lock = ["free-running", "acquiring SYNC", "SYNC-locked"][s.get("sync_lock_state", 0)]
    print(f"p50 {s['lateness_p50_us']} us, p99 {s['lateness_p99_us']} us, "
          f"max {s['lateness_max_us']} us, work p99 {s['work_p99_us']} us, overruns {s['overruns']}"
          f" of {s['ticks']} ticks, SYNCs {s.get('syncs', 0)} ({lock} at exit)")
else:
    print(f"enabled {d['enabled_axes']}, work p50/p99/max {s['work_p50_us']}/{s['work_p99_us']}/"
          f"{s['work_max_us']} us, overruns {s['overruns']} of {s['ticks']}")
