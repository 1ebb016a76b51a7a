#!/usr/bin/env bash
# SYNC -> TPDO latency over vcan0 (inside user-mode Linux where the kernel has no CAN: the
# figure then includes UML's scheduling noise). Usage: [MODE=--lockstep] bench/sync-latency.sh [N]
set -euo pipefail
cd "$(dirname "$(readlink -f "$0")")/.."
cargo build --release -q -p drive-emu
bin=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release/drive-emu
./vcan-setup.sh -- sh -c "$bin run --iface vcan0 --node 5 --rt-priority 0 --duration 30 ${MODE:-} 2>/dev/null & sleep 0.5; python3 bench/sync_latency.py vcan0 5 ${1:-2000}; kill %1 2>/dev/null; wait"
