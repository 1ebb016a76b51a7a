#!/usr/bin/env bash
# Loop lateness of `drive-emu run` (the real-time loop's own measurement: each control tick's
# wake-up minus its deadline, on the monotonic clock, in a histogram allocated up front; the
# exit statistics of `--json`) beside cyclictest (rt-tests), one after the other in ONE
# user-mode-Linux boot with vcan0, SCHED_FIFO 80, at 1 kHz: cyclictest, drive-emu free-running
# (no SYNC), drive-emu SYNC-locked (bench/sync_master.py, SCHED_FIFO 90, a SYNC every 1 ms on an
# absolute schedule). Then, on the host, how much work one loop does per tick for 32/64/127
# axes (examples/loop_bench, in-process bus).
#   bench/loop-jitter.sh [SECONDS]        (needs: apt-get install rt-tests can-utils)
set -euo pipefail
cd "$(dirname "$(readlink -f "$0")")/.."
secs=${1:-10}
for c in cyclictest cansend chrt; do
    command -v $c >/dev/null || { echo "$c missing: apt-get install rt-tests can-utils" >&2; exit 1; }
done
cargo build --release -q -p drive-emu --bin drive-emu --example loop_bench
dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
loops=$((secs * 1000))
./vcan-setup.sh -q -- sh -c "
# cyclictest: same priority, same period; its histogram gives p50/p99.
cyclictest -q -m -p80 -t1 -i1000 -l$loops -h20000 2>/dev/null > $work/ct
awk -v n=$loops '
    /^[0-9]/ { c += \$2; if (!p50 && c >= n*0.50) p50 = \$1+0; if (!p99 && c >= n*0.99) p99 = \$1+0 }
    /Max Latencies/ { max = \$NF+0 }
    END { printf \"1 kHz  cyclictest            : p50 %d us, p99 %d us, max %d us\\n\", p50, p99, max }' $work/ct
$dir/drive-emu run --iface vcan0 --node 5 --rt-priority 80 --duration $secs --json 2>/dev/null > $work/free
printf '1 kHz  drive-emu free-running : '; python3 bench/fmt_stats.py lateness < $work/free
$dir/drive-emu run --iface vcan0 --node 5 --rt-priority 80 --duration $((secs + 60)) --json 2>/dev/null > $work/sync & emu=\$!
sleep 0.5; cansend vcan0 000#0105; chrt -f 90 python3 bench/sync_master.py vcan0 $loops 0.001; kill -TERM \$emu; wait \$emu
printf '1 kHz  drive-emu SYNC-locked  : '; python3 bench/fmt_stats.py lateness < $work/sync
"
for axes in 32 64 127; do   # 127: every node ID a CANopen bus has
    echo "axes $axes at 1 kHz (host, in-process bus): $("$dir/examples/loop_bench" "$axes" 1000 "$secs" 80 2>/dev/null | python3 bench/fmt_stats.py axes)"
done
