#!/usr/bin/env bash
# SYNC -> TPDO and SDO upload latency over vcan0 of `run` (real-time) and `run --lockstep`, in
# one user-mode-Linux boot (where the kernel has no CAN: the figures then include UML's
# scheduling noise; compare the two modes within one run). SCHED_FIFO 80 inside UML.
#   bench/sync-latency.sh [N_SYNCS]
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
done"
