#!/usr/bin/env bash
# SYNC -> TPDO and SDO upload latency over vcan0 of `run` (real-time) and `run --lockstep`, in
# one user-mode-Linux boot (where the kernel has no CAN: the figures then include UML's
# scheduling noise; compare the two modes within one run). SCHED_FIFO 80 inside UML.
#   bench/sync-latency.sh [N_SYNCS]
# With CANOPEND=/path/to/canopend (CANopenNode's CANopenLinux, built by you), the same
# measurement of canopend (node 5, its TPDO2 made synchronous over SDO) in the same boot.
# With PANEL=1, each mode also runs with the live panel open (`--panel 127.0.0.1:8080`) and 5
# clients reading its stream (curl), right after the same mode without it.
set -euo pipefail
cd "$(dirname "$(readlink -f "$0")")/.."
cargo build --release -q -p drive-emu
bin=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release/drive-emu
n=${1:-3000}
./vcan-setup.sh -- sh -c "
panels=no
[ -n '${PANEL:-}' ] && panels='no yes'
for mode in '' '--lockstep' '' '--lockstep'; do
  for p in \$panels; do
    extra=''; label=''
    [ \$p = yes ] && extra='--panel 127.0.0.1:8080' && label=' +panel, 5 clients'
    $bin run --iface vcan0 --node 5 --rt-priority 80 --duration 60 \$mode \$extra 2>/dev/null & pid=\$!
    sleep 0.5
    clients=''
    if [ \$p = yes ]; then
      for c in 1 2 3 4 5; do
        curl -sN http://127.0.0.1:8080/api/stream >/dev/null 2>&1 & clients=\"\$clients \$!\"
      done
      sleep 0.5
    fi
    python3 bench/sync_latency.py vcan0 5 $n 0.001 \"run \$mode\$label\"
    [ -n \"\$clients\" ] && kill \$clients 2>/dev/null
    kill \$pid 2>/dev/null; wait \$pid 2>/dev/null
  done
done
if [ -n '${CANOPEND:-}' ]; then
  # canopend reports a storage error (and refuses NMT operational) until its files exist:
  # a first start stores its parameters (0x1010:1 = 'save').
  rm -rf /tmp/canopend-storage; mkdir -p /tmp/canopend-storage
  ${CANOPEND:-} vcan0 -i 5 -s /tmp/canopend-storage/ >/dev/null 2>&1 & pid=\$!
  sleep 0.5; cansend vcan0 605#2310100173617665; sleep 0.5
  kill \$pid 2>/dev/null; wait \$pid 2>/dev/null
  for i in 1 2; do
    chrt -f 80 ${CANOPEND:-} vcan0 -i 5 -s /tmp/canopend-storage/ >/dev/null 2>&1 & pid=\$!
    sleep 0.5
    python3 bench/sync_latency.py vcan0 5 $n 0.001 canopend --map-tpdo2
    kill \$pid 2>/dev/null; wait \$pid 2>/dev/null
  done
fi"
