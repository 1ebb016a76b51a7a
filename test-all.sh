#!/usr/bin/env bash
# Run the whole test suite:
#   1. host tests (protocol, emulator): cargo nextest run --workspace --exclude e2e
#   1a. runtime and emulator without SocketCAN: libraries, binary and bus tests built and run with
#      --no-default-features (the cargo feature `socketcan` off, as where there is no SocketCAN:
#      portability; the rest of the suite is the same code either way)
#   1b. every `cargo fuzz` target (`cargo fuzz list`) built once, each run for a bounded time
#      (frames FUZZ_SECONDS, default 30, the others FUZZ_SECONDS_EACH, default 8), RSS capped,
#      any crash fails (stable Rust, no sanitizer, overflow checks on; needs cargo-fuzz)
#   2. end-to-end tests on a real virtual CAN bus (package e2e): built and archived here
#      with `cargo nextest archive` (before 1b), then run from the archive through ./vcan-setup.sh
#      in the background while 1b, 3 and 3b run (its output is printed when it ends)
#      (natively where the kernel has CAN, inside user-mode Linux otherwise), followed in
#      the same vcan run by the python package's pytest tests (python/tests: the drive_emu
#      fixture and the examples; needs `pip install ./python`; "no tests" fails).
#   3. the Python module's tests on the host (python/drive-emu/tests: sim and sweep against the
#      CLI, Dask, Ctrl-C, the Fig. 11 example; needs `pip install './python/drive-emu[all]'`,
#      again after a change of the Rust code, and pytest's "no tests" fails).
#   3b. both Python packages at the lowest versions their pyproject.toml allow (python/lowest.txt,
#      python/drive-emu/lowest.txt) in a fresh venv: the module's tests and python/tests (over
#      socketcand where the host has no vcan0).
# Exits non-zero if any phase fails (all always run). See docs/vcan.md.
#
# Environment: VCAN_TIMEOUT (seconds, default 1800) bounds the vcan phase, FUZZ_SECONDS and
# FUZZ_SECONDS_EACH the fuzz runs; TEST_ALL_FREE_DISK=1 (set by .ci/run) deletes the debug build once the e2e archive is made and the fuzz build after its run; the CARGO_TARGET_DIR, DRIVE_EMU_* and NEXTEST_* variables reach the e2e tests.
set -euo pipefail

case "${1:-}" in
    -h|--help) sed -n '2,25p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    "") ;;
    *) echo "test-all.sh: no arguments expected (see --help)" >&2; exit 2 ;;
esac

cd "$(dirname "$(readlink -f "$0")")"
ROOT=$PWD

now() { date +%s.%N; }
secs() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }'; }
banner() { printf '\n==== %s\n' "$*"; }

tmp=$(mktemp -d "${TMPDIR:-/tmp}/test-all.XXXXXX")
vcan_pid=
trap '[[ -z $vcan_pid ]] || kill "$vcan_pid" 2>/dev/null; rm -rf "$tmp"' EXIT

# ---- 1. host tests
banner "host tests: cargo nextest run --workspace --exclude e2e"
t=$(now); host_rc=0
cargo nextest run --workspace --exclude e2e --no-fail-fast || host_rc=$?
host_time=$(secs "$t")

# ---- 1a. the emulator with the SocketCAN feature off (builds and passes without it)
nosc=(-p drive-runtime -p drive-emu --no-default-features --features drive-emu/panel --lib --bins --test socketcand_bus
    --test socketcand_run --test cli_validation --test layering)
banner "host tests without SocketCAN: cargo nextest run ${nosc[*]}"
t=$(now); nosc_rc=0
cargo nextest run "${nosc[@]}" --no-fail-fast || nosc_rc=$?
nosc_time=$(secs "$t")

# ---- 2. vcan (e2e) tests
banner "vcan tests: build + archive e2e on the host, run it through ./vcan-setup.sh"
t=$(now); e2e_rc=0
archive=$tmp/e2e.tar.zst
mkdir "$tmp/extract"
# The emulator binary, for e2e tests that start it as a process (e2e::drive_emu_bin(),
# see docs/vcan.md): built here, before the archive, in whatever target dir cargo uses
# (CARGO_TARGET_DIR or the workspace's target/), unless DRIVE_EMU_BIN names one already.
emu_ok=1
if [[ -z ${DRIVE_EMU_BIN:-} ]]; then
    if cargo build --release -p drive-emu --bin drive-emu; then
        tdir=$(cargo metadata --no-deps --format-version 1 |
            python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])') ||
            tdir=${CARGO_TARGET_DIR:-$ROOT/target}
        export DRIVE_EMU_BIN=$tdir/release/drive-emu
        [[ -x $DRIVE_EMU_BIN ]] || { echo "test-all.sh: $DRIVE_EMU_BIN missing after the build" >&2; emu_ok=0; }
    else
        echo "test-all.sh: building drive-emu failed" >&2; emu_ok=0
    fi
fi
if [[ $emu_ok == 1 ]] && cargo nextest archive -p e2e --archive-file "$archive"; then
    echo "test-all.sh: DRIVE_EMU_BIN=$DRIVE_EMU_BIN"
    build_time=$(secs "$t"); t=$(now)
    # nextest, then pytest (python/tests), both inside one vcan run; either failing fails it.
    # pytest's exit 5 (no tests collected) is non-zero and so fails too.
    if ! python3 -c 'import drive_emu_testing' 2>/dev/null; then
        echo "test-all.sh: python package drive_emu_testing missing: pip install ./python" >&2
    fi
    # In the background (user-mode Linux keeps about one core busy) while the fuzz runs and
    # the Python tests use the other; its output is printed when it ends. `trap - INT`: an
    # asynchronous command would otherwise start with SIGINT ignored (tests send Ctrl-C).
    (
        trap - INT
        exec ./vcan-setup.sh --ifaces 2 --timeout "${VCAN_TIMEOUT:-1800}" -- bash -c '
        rc=0
        cargo nextest run --archive-file "$1" --workspace-remap "$2" \
            --extract-to "$3" --no-fail-fast || rc=$?
        printf "\n==== python tests: pytest python/tests (drive_emu fixture, examples)\n"
        python3 -m pytest -p no:cacheprovider -q python/tests || { py=$?; echo "pytest: exit $py"; rc=1; }
        exit $rc' vcan-tests "$archive" "$ROOT" "$tmp/extract"
    ) >"$tmp/vcan.log" 2>&1 &
    vcan_pid=$!; vcan_t=$(now)
    # What runs beside it from here (fuzz, the Python phases) at a lower priority: the e2e
    # tests inside user-mode Linux share its one CPU among a drive, a master and sometimes a
    # browser, and a master once waited 10 s for an SDO answer while the fuzz build held both
    # host cores. The vcan run keeps its priority (forked above); the rest fills the idle core.
    renice -n 10 -p $$ >/dev/null 2>&1 || true
    # The debug build (host tests, the archive's source) is not needed from here on: in CI its
    # room goes to the fuzz build.
    if [[ ${TEST_ALL_FREE_DISK:-0} == 1 ]]; then
        debug_dir=$(cargo metadata --no-deps --format-version 1 |
            python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])') &&
            [[ -n $debug_dir && -d $debug_dir/debug ]] && rm -rf "${debug_dir:?}/debug"
    fi
    echo "test-all.sh: the vcan run goes on in the background (pid $vcan_pid); its output follows when it ends"
else
    e2e_rc=$?
    build_time=$(secs "$t"); run_time=0
    echo "test-all.sh: building/archiving the e2e tests failed" >&2
fi

# ---- 1b. bounded fuzz runs: every target `cargo fuzz list` names (a new one joins without
# an edit here), seeded from fuzz/seeds/TARGET when that exists; -s none: sanitizers need
# nightly; -a: debug assertions and overflow checks; -rss_limit_mb makes unbounded memory a
# crash, -timeout an input that runs for ever. Each target's new corpus is thrown away.
# --codegen-units 16: the build (the whole emulator) in a third of the time, the runs a little slower.
banner "fuzz: every cargo fuzz target, frames ${FUZZ_SECONDS:-30} s, the others ${FUZZ_SECONDS_EACH:-8} s each"
t=$(now); fuzz_rc=0; fuzz_failed=()
if cargo fuzz --version >/dev/null 2>&1; then
    if (cd fuzz && cargo fuzz build --sanitizer none --debug-assertions --codegen-units 16) &&
        fuzz_targets=$(cd fuzz && cargo fuzz list) && [[ -n $fuzz_targets ]]; then
        for target in $fuzz_targets; do
            fuzz_s=${FUZZ_SECONDS_EACH:-8}
            [[ $target == frames ]] && fuzz_s=${FUZZ_SECONDS:-30}
            corpus=$tmp/fuzz-corpus/$target
            mkdir -p "$corpus"
            seeds=()
            [[ -d fuzz/seeds/$target ]] && seeds=("seeds/$target")
            banner "fuzz: $target for $fuzz_s s"
            (cd fuzz && cargo fuzz run --sanitizer none --debug-assertions --codegen-units 16 "$target" \
                "$corpus" "${seeds[@]}" -- -max_total_time="$fuzz_s" -rss_limit_mb=1024 \
                -timeout=10 -print_final_stats=1) || fuzz_failed+=("$target")
        done
        if ((${#fuzz_failed[@]})); then
            echo "test-all.sh: fuzz targets that failed: ${fuzz_failed[*]} (inputs in fuzz/artifacts/)" >&2
            fuzz_rc=1
        fi
    else
        echo "test-all.sh: the fuzz targets did not build, or cargo fuzz list named none" >&2
        fuzz_rc=1
    fi
else
    echo "test-all.sh: cargo-fuzz missing: cargo install cargo-fuzz --version 0.13.2 --locked" >&2
    fuzz_rc=127
fi
fuzz_time=$(secs "$t")
if [[ ${TEST_ALL_FREE_DISK:-0} == 1 ]]; then rm -rf fuzz/target; fi
df -h . | tail -n 1

# ---- 3. the Python module (drive_emu), on the host: compared with the CLI binary built above
banner "python module tests: pytest python/drive-emu/tests"
t=$(now); py_rc=0
if ! python3 -c 'import drive_emu' 2>/dev/null; then
    echo "test-all.sh: python module drive_emu missing: pip install './python/drive-emu[all]'" >&2
fi
if [[ $emu_ok == 1 ]]; then
    python3 -m pytest -p no:cacheprovider -q python/drive-emu/tests || py_rc=$?
else
    echo "test-all.sh: no drive-emu binary to compare the module with" >&2; py_rc=1
fi
py_time=$(secs "$t")

# ---- 3b. both Python packages at the lowest versions they allow, in a fresh venv: the
# module's tests and the fixture's (python/tests: on this host's vcan0 if it has one, else
# over socketcand)
banner "python packages at their lowest versions: python/lowest.txt, python/drive-emu/lowest.txt"
t=$(now); low_rc=0
if [[ $emu_ok == 1 ]]; then
    (
        set -e
        # the wheel .ci/run built and installed (DRIVE_EMU_WHEEL), else built here
        if [[ -n ${DRIVE_EMU_WHEEL:-} && -f $DRIVE_EMU_WHEEL ]]; then
            mkdir -p "$tmp/wheel" && cp "$DRIVE_EMU_WHEEL" "$tmp/wheel/"
        else
            python3 -m pip wheel -q --disable-pip-version-check --no-deps -w "$tmp/wheel" ./python/drive-emu
        fi
        python3 -m venv "$tmp/lowest"
        "$tmp/lowest/bin/pip" install -q --disable-pip-version-check \
            -r python/lowest.txt -r python/drive-emu/lowest.txt ./python
        "$tmp/lowest/bin/pip" install -q --disable-pip-version-check --no-deps "$tmp"/wheel/drive_emu-*.whl
        "$tmp/lowest/bin/pip" list --format=freeze | grep -iE '^(numpy|pandas|python-can|canopen)='
        "$tmp/lowest/bin/python" -m pytest -p no:cacheprovider -q python/drive-emu/tests python/tests
    ) || low_rc=$?
else
    echo "test-all.sh: no drive-emu binary to test the packages with" >&2; low_rc=1
fi
low_time=$(secs "$t")
rm -rf "$tmp/lowest" "$tmp/wheel"

# ---- 2 (end). the vcan run started above
if [[ -n $vcan_pid ]]; then
    banner "vcan tests: waiting for the run started in the background"
    wait "$vcan_pid" || e2e_rc=$?
    vcan_pid=
    run_time=$(secs "$vcan_t")
    cat "$tmp/vcan.log"
fi

banner "summary"
printf 'host tests: %s (%ss)\n' "$([[ $host_rc == 0 ]] && echo ok || echo "FAILED ($host_rc)")" "$host_time"
printf 'host tests without SocketCAN: %s (%ss)\n' "$([[ $nosc_rc == 0 ]] && echo ok || echo "FAILED ($nosc_rc)")" "$nosc_time"
printf 'fuzz run: %s (%ss)\n' "$([[ $fuzz_rc == 0 ]] && echo ok || echo "FAILED ($fuzz_rc)")" "$fuzz_time"
printf 'vcan tests: %s (build+archive %ss, run via vcan-setup.sh %ss, beside phases 1b, 3 and 3b)\n' \
    "$([[ $e2e_rc == 0 ]] && echo ok || echo "FAILED ($e2e_rc)")" "$build_time" "$run_time"
printf 'python module tests: %s (%ss)\n' "$([[ $py_rc == 0 ]] && echo ok || echo "FAILED ($py_rc)")" "$py_time"
printf 'python packages at their lowest versions: %s (%ss)\n' "$([[ $low_rc == 0 ]] && echo ok || echo "FAILED ($low_rc)")" "$low_time"
if [[ $host_rc != 0 || $nosc_rc != 0 || $fuzz_rc != 0 || $e2e_rc != 0 || $py_rc != 0 || $low_rc != 0 ]]; then exit 1; fi
