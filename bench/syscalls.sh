#!/usr/bin/env bash
# System calls per SYNC of `run` (real-time) and `run --lockstep`, in one user-mode-Linux boot:
# strace -c attached to every thread of the drive while bench/sync_latency.py sends N SYNCs at
# 1 kHz (and an SDO every tenth); in UML every system call is a round trip through the host
# (ptrace), so these counts explain the latency gap between the two modes.
#   bench/syscalls.sh [N_SYNCS]
set -euo pipefail
cd "$(dirname "$(readlink -f "$0")")/.."
command -v strace >/dev/null || { echo "strace missing: apt-get install strace" >&2; exit 1; }
cargo build --release -q -p drive-emu
bin=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release/drive-emu
n=${1:-1000}
./vcan-setup.sh -q -- sh -c "
for mode in '' '--lockstep'; do
  $bin run --iface vcan0 --node 5 --rt-priority 80 --duration 120 \$mode 2>/dev/null & pid=\$!
  sleep 0.5
  strace -c -f -qq -p \$pid -o /tmp/strace.\$\$ & st=\$!
  sleep 0.5
  python3 bench/sync_latency.py vcan0 5 $n 0.001 \"run \$mode (under strace)\"
  kill -INT \$st; wait \$st 2>/dev/null
  kill \$pid 2>/dev/null; wait \$pid 2>/dev/null
  echo \"--- run \$mode: calls per SYNC (over $n SYNCs and $((n / 10)) SDOs)\"
  awk -v n=$n '\$NF != \"total\" && \$NF ~ /^[a-z_0-9]+\$/ && \$4 ~ /^[0-9]+\$/ { printf \"  %-16s %8.2f\\n\", \$NF, \$4 / n; tot += \$4 } END { printf \"  %-16s %8.2f\\n\", \"total\", tot / n }' /tmp/strace.\$\$
  rm -f /tmp/strace.\$\$
done"
