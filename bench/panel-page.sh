#!/usr/bin/env bash
# What the live panel's page costs a browser: inside one user-mode-Linux boot (vcan0), a drive
# `run --panel` moved by the reference master (`demo --iface`, CSP cruise at 10 mm/s), and
# Chromium's headless shell showing the page; per plot span the share of wall time the page's
# main thread is busy and the drawings per second (emulator/benches/panel_page.rs, --url).
#   bench/panel-page.sh [SECONDS]
# OLD_BIN=/path/to/drive-emu measures that build's page too, in the same boot (e.g. a
# `git worktree` of an earlier commit, built with cargo build --release).
set -euo pipefail
cd "$(dirname "$(readlink -f "$0")")/.."
cargo build --release -q -p drive-emu
bin=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release/drive-emu
bench=$(cargo bench -q -p drive-emu --bench panel_page --no-run --message-format=json 2>/dev/null |
  python3 -c 'import json,sys
for m in map(json.loads, sys.stdin):
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["name"] == "panel_page":
        print(m["executable"])')
secs=${1:-10}
./vcan-setup.sh --timeout 1800 -- sh -c "
for b in $bin ${OLD_BIN:-}; do
  for round in ${ROUNDS:-1 2}; do
    \$b run --iface vcan0 --node 5 --rt-priority 0 --no-mlock --panel 127.0.0.1:8080 \
      --panel-dir /tmp/panel-page-rec >/dev/null 2>&1 & drive=\$!
    sleep 1
    \$b demo --iface vcan0 --node 5 --cruise-s 300 >/dev/null 2>&1 & master=\$!
    $bench --url http://127.0.0.1:8080/ --label \"\$b #\$round: \" $secs || true
    kill \$master \$drive 2>/dev/null; wait \$master \$drive 2>/dev/null
  done
done"
