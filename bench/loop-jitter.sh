#!/usr/bin/env bash
# Loop lateness of drive-emu's real-time loop beside cyclictest (rt-tests), in one measurement,
# at 1 kHz and 4 kHz; then how many axes one loop serves at 1 kHz.
#   bench/loop-jitter.sh [SECONDS]        (needs: apt-get install rt-tests; root for SCHED_FIFO)
set -euo pipefail
cd "$(dirname "$(readlink -f "$0")")/.."
secs=${1:-10}
cargo build --release -q -p drive-emu --example loop_bench
bin=${CARGO_TARGET_DIR:-target}/release/examples/loop_bench
command -v cyclictest >/dev/null || { echo "cyclictest missing: apt-get install rt-tests" >&2; exit 1; }
for hz in 1000 4000; do
    interval=$((1000000 / hz)); loops=$((secs * hz))
    # cyclictest: same priority, same CPU, same period; its histogram gives p50/p99.
    ct=$(cyclictest -q -m -p80 -a1 -t1 -i"$interval" -l"$loops" -h20000 2>/dev/null)
    ct_p=$(printf '%s\n' "$ct" | awk -v n="$loops" '
        /^[0-9]/ { c += $2; if (!p50 && c >= n*0.50) p50 = $1+0; if (!p99 && c >= n*0.99) p99 = $1+0 }
        /Max Latencies/ { max = $NF+0 }
        END { printf "p50 %d us, p99 %d us, max %d us", p50, p99, max }')
    ours=$("$bin" 1 "$hz" "$secs" 80 2>/dev/null)
    echo "$hz Hz  cyclictest: $ct_p"
    echo "$hz Hz  drive-emu : $(printf '%s' "$ours" | python3 bench/fmt_stats.py lateness)"
done
for axes in 32 64 127; do   # 127: every node ID a CANopen bus has
    echo "axes $axes at 1 kHz: $("$bin" "$axes" 1000 "$secs" 80 2>/dev/null | python3 bench/fmt_stats.py axes)"
done
