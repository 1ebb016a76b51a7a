#!/usr/bin/env bash
# Many axes in ONE `drive-emu run` (real-time loop, SCHED_FIFO 80) on vcan0 inside user-mode
# Linux: a SYNC master at 1 kHz (bench/sync_master.py, SCHED_FIFO 90) sends N SYNCs; in the
# middle the drive is stopped (SIGSTOP) for STALL_MS and resumed. A `candump -L` capture (64 MiB
# receive buffer, SCHED_FIFO 85, -d: its own drops reported) counts the TPDO2/3/4 of every
# node per SYNC (frames lost: target 0), and the drive's exit statistics
# (--json) give its own counters (tx dropped, tx full waits, rx overflows) and loop lateness.
#   bench/axes.sh [N_SYNCS] [AXES...]      (default: 3000 SYNCs, 16 and 127 axes)
#   STALL_MS=1000 (0: no stop); NETDEV_BACKLOG=1000000 (the kernel's default 1000 loses frames)
set -euo pipefail
cd "$(dirname "$(readlink -f "$0")")/.."
cargo build --release -q -p drive-emu
bin=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release/drive-emu
n=${1:-3000}; shift || true
axes_list=${*:-16 127}
stall_ms=${STALL_MS:-1000}
backlog=${NETDEV_BACKLOG:-1000000}
for c in candump cansend chrt; do
    command -v $c >/dev/null || { echo "$c missing: apt-get install can-utils util-linux" >&2; exit 1; }
done
work=$(mktemp -d)
[ -n "${KEEP:-}" ] || trap 'rm -rf "$work"' EXIT
for axes in $axes_list; do
    { echo "tick_hz = 1000"
      for id in $(seq 1 "$axes"); do printf '[[axis]]\nnode_id = %d\npreset = "cnc1"\n' "$id"; done
    } > "$work/m$axes.toml"
done
./vcan-setup.sh -q -- sh -c "
set -e
# vcan hands every frame to the receive backlog (netif_rx, at most netdev_max_backlog = 1000
# frames), drained in a softirq; with SCHED_FIFO tasks busy, ksoftirqd starves and frames
# beyond 1000 are dropped silently (softnet_stat column 2): allow a whole burst.
sysctl -q -w net.core.netdev_max_backlog=$backlog
for axes in $axes_list; do
  drops0=\$(python3 -c 'print(sum(int(l.split()[1], 16) for l in open(\"/proc/net/softnet_stat\")))')
  cap=$work/cap\$axes.log; st=$work/st\$axes.json
  # Only SYNC and TPDO2/3/4 (kernel filters), block-buffered (one write per 4 KiB, not per
  # frame; SIGTERM makes it flush and exit), and above the drive's priority: on one CPU it must
  # read up to 381 frames per SYNC or its receive queue overflows (it did at FIFO 70).
  chrt -f 85 candump -L -d -r 67108864 vcan0,080:7FF,280:780,380:780,480:780 > \$cap & dump=\$!
  $bin run --iface vcan0 --config $work/m\$axes.toml --rt-priority 80 --json --ready > \$st 2>$work/err\$axes & emu=\$!
  for i in \$(seq 1 300); do grep -q ready \$st 2>/dev/null && break; sleep 0.1; done
  cansend vcan0 000#0100; sleep 0.5
  # SYNCs from here: the ones before are not counted (the capture starts counting at the first)
  chrt -f 90 python3 bench/sync_master.py vcan0 $n 0.001 & gen=\$!
  if [ $stall_ms -gt 0 ]; then
    sleep \$(python3 -c 'print($n / 2000)'); kill -STOP \$emu
    sleep \$(python3 -c 'print($stall_ms / 1000)'); kill -CONT \$emu
  fi
  wait \$gen
  # The backlog is answered before an SDO request sent after it (frames in bus order).
  ans=\$(printf '%03X' \$((0x580 + axes)))
  candump -n 1 -T 120000 vcan0,\$ans:7FF > /dev/null & wait_ans=\$!
  sleep 0.2
  cansend vcan0 \$(printf '%03X' \$((0x600 + axes)))#4000100000000000
  wait \$wait_ans || echo \"no SDO answer from node \$axes within 120 s\" >&2
  sleep 0.5
  kill -TERM \$emu; wait \$emu || true
  kill -TERM \$dump; wait \$dump 2>/dev/null || true
  drops1=\$(python3 -c 'print(sum(int(l.split()[1], 16) for l in open(\"/proc/net/softnet_stat\")))')
  python3 bench/axes_count.py \$cap \$st \$axes \"\$axes axes\" || cat $work/err\$axes >&2
  echo \"\$axes axes: kernel receive backlog drops (softnet_stat): \$((drops1 - drops0))\"
done"
