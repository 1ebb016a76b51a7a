#!/usr/bin/env bash
# What the live panel's page costs a browser: inside one user-mode-Linux boot (vcan0), a drive
# `run --panel` moved by the reference master (`demo --iface`, CSP cruise at 10 mm/s, then the
# same with 0.05 mm backlash), and Chromium's headless shell showing the page; per plot span
# the share of wall time the page's main thread is busy (bench/panel_page.py).
#   bench/panel-page.sh [SECONDS]
# OLD_BIN=/path/to/drive-emu measures that build's page too, in the same boot (e.g. a
# `git worktree` of an earlier commit, built with cargo build --release).
set -euo pipefail
cd "$(dirname "$(readlink -f "$0")")/.."
cargo build --release -q -p drive-emu
bin=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release/drive-emu
secs=${1:-10}
./vcan-setup.sh --timeout 1800 -- sh -c "
for b in $bin ${OLD_BIN:-}; do
  for round in ${ROUNDS:-1 2}; do
    \$b run --iface vcan0 --node 5 --rt-priority 0 --no-mlock --panel 127.0.0.1:8080 \
      --panel-dir /tmp/panel-page-rec >/dev/null 2>&1 & drive=\$!
    sleep 1
    \$b demo --iface vcan0 --node 5 --cruise-s 300 >/dev/null 2>&1 & master=\$!
    python3 bench/panel_page.py http://127.0.0.1:8080/ --seconds $secs --label \"\$b #\$round\" || true
    kill \$master \$drive 2>/dev/null; wait \$master \$drive 2>/dev/null
  done
done"
