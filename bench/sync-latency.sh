#!/usr/bin/env bash
# SYNC -> TPDO and SDO upload latency over vcan0 of `run` (real-time) and `run --lockstep`, in
# one user-mode-Linux boot (where the kernel has no CAN: the figures then include UML's
# scheduling noise; compare the two modes within one run). SCHED_FIFO 80 inside UML.
#   bench/sync-latency.sh [N_SYNCS]
# With CANOPEND=/path/to/canopend (CANopenNode's CANopenLinux, built by you), the same
# measurement of canopend (node 5, its TPDO2 made synchronous over SDO) in the same boot.
set -euo pipefail
cd "$(dirname "$(readlink -f "$0")")/.."
cargo build --release -q -p drive-emu
bin=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release/drive-emu
n=${1:-3000}
./vcan-setup.sh -- sh -c "
for mode in '' '--lockstep' '' '--lockstep'; do
  $bin run --iface vcan0 --node 5 --rt-priority 80 --duration 60 \$mode 2>/dev/null & pid=\$!
  sleep 0.5
  python3 bench/sync_latency.py vcan0 5 $n 0.001 \"run \$mode\"
  kill \$pid 2>/dev/null; wait \$pid 2>/dev/null
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
