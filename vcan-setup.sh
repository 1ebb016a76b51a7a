#!/usr/bin/env bash
# vcan-setup.sh: give a command a real (virtual) CAN bus, vcan0..vcan{N-1}.
#
# Where the running kernel has CAN, the vcan interfaces are created natively and the
# command runs here. Where it has not (AF_CAN -> EAFNOSUPPORT, as on our dev and CI
# machines), a user-mode Linux kernel (Debian package `user-mode-linux`) is booted as an
# ordinary process with this machine's `/` as its root filesystem (hostfs); it loads
# the CAN modules, brings vcan0.. up and runs the command inside, in the same directory
# with the same PATH/HOME/cargo/rustup environment. See docs/vcan.md.
set -euo pipefail

PROG=vcan-setup.sh
HARNESS_FAIL=125 # our own failures (like timeout(1)); the command's status otherwise

usage() {
    cat <<'EOF'
Usage: vcan-setup.sh [OPTIONS] [--] [COMMAND [ARGS...]]

Provide virtual CAN interfaces vcan0..vcan{N-1} and run COMMAND with them.

  * Kernel with CAN support: create and bring up vcan0.. natively (idempotent; needs
    root or existing interfaces), then run COMMAND here, if given.
  * Kernel without CAN support: boot user-mode Linux (linux.uml) with this machine's /
    as root (hostfs), bring up vcan0.. inside it and run COMMAND there, in the current
    directory. COMMAND is required in this mode.

The exit status is COMMAND's. If the vcan interfaces cannot be had (no UML, modules
fail to load, vcan0 not up, UML does not boot), the script fails with status 125 and
says why; it never skips.

Options:
  --ifaces N      number of interfaces (vcan0..vcan{N-1}); default 1
  --timeout SECS  kill the command / UML after SECS seconds (default: no limit)
  --install-uml   (root) make a user-mode Linux that boots on this CPU available, then
                  exit: the distribution's linux.uml if it boots here, else Debian
                  testing's kernel and modules with their own C library in
                  /opt/vcan-uml (apt-get download, patchelf). Older UML kernels (6.1,
                  6.12) cannot boot on CPUs with AVX-512/AMX state ("ptrace set fp
                  regs failed, errno = 14"); 7.x can. See docs/vcan.md.
  -q, --quiet     no progress lines on stderr
  -h, --help      this help

Environment:
  VCAN_MODE       auto (default) | native | uml  -- force a mode
  VCAN_PASS_ENV   space-separated extra variable names to pass into UML. Always passed:
                  PATH HOME USER LOGNAME LANG LC_ALL TERM TMPDIR CI CARGO_HOME RUSTUP_HOME
                  RUSTUP_TOOLCHAIN CARGO_TARGET_DIR CARGO_TERM_COLOR NO_COLOR
                  PYENV_ROOT PYENV_VERSION VIRTUAL_ENV PYTHONPATH and every RUST_*,
                  NEXTEST_*, DRIVE_EMU_* variable.
  VCAN_UML_MEM    UML memory (default 2G)
  VCAN_UML_KERNEL path of linux.uml (default: /opt/vcan-uml/linux.uml if --install-uml
                  put one there, else from PATH)
  VCAN_UML_MODULES  UML module dir (default: the modules beside that kernel,
                  /usr/lib/uml/modules/<linux.uml version> for the distribution's)
  VCAN_UML_SUITE  Debian suite --install-uml takes the kernel from (default: forky)

Examples:
  ./vcan-setup.sh -- sh -c 'ip -details link show vcan0'
  ./vcan-setup.sh --ifaces 2 -- cargo nextest run -p e2e
  sudo ./vcan-setup.sh --ifaces 2        # CAN-capable kernel: just create vcan0, vcan1
EOF
}

NIFACES=1
TIMEOUT=0
QUIET=0
INSTALL_UML=0
UML_DIR=/opt/vcan-uml
while [[ $# -gt 0 ]]; do
    case "$1" in
        -h|--help) usage; exit 0 ;;
        --ifaces) [[ $# -ge 2 ]] || { echo "$PROG: --ifaces needs a number" >&2; exit 2; }
                  NIFACES=$2; shift 2 ;;
        --ifaces=*) NIFACES=${1#*=}; shift ;;
        --timeout) [[ $# -ge 2 ]] || { echo "$PROG: --timeout needs seconds" >&2; exit 2; }
                   TIMEOUT=$2; shift 2 ;;
        --timeout=*) TIMEOUT=${1#*=}; shift ;;
        -q|--quiet) QUIET=1; shift ;;
        --install-uml) INSTALL_UML=1; shift ;;
        --) shift; break ;;
        -*) echo "$PROG: unknown option $1 (see --help)" >&2; exit 2 ;;
        *) break ;;
    esac
done
if ! [[ $NIFACES =~ ^[0-9]+$ ]] || (( NIFACES < 1 || NIFACES > 64 )); then
    echo "$PROG: --ifaces must be 1..64, got '$NIFACES'" >&2; exit 2
fi
if ! [[ $TIMEOUT =~ ^[0-9]+$ ]]; then
    echo "$PROG: --timeout must be whole seconds, got '$TIMEOUT'" >&2; exit 2
fi
CMD=("$@")
MODE=${VCAN_MODE:-auto}

say() { (( QUIET )) || echo "$PROG: $*" >&2; }
die() { echo "$PROG: ERROR: $*" >&2; exit "$HARNESS_FAIL"; }
now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.2f", b - a }'; }
ifnames() { local i; for ((i = 0; i < NIFACES; i++)); do echo "vcan$i"; done; }

# ---------------------------------------------------------------- native mode
kernel_has_can() {
    # Loading may fail (no modules, not root); the probe below decides.
    modprobe -q can 2>/dev/null || true
    modprobe -q can-raw 2>/dev/null || true
    if command -v python3 >/dev/null 2>&1; then
        python3 - <<'EOF' 2>/dev/null
import socket
s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
s.close()
EOF
    else
        [[ -e /proc/net/can ]]
    fi
}

iface_is_up() { ip -o link show dev "$1" 2>/dev/null | grep -q '[<,]UP[,>]'; }

native_setup() {
    modprobe -q vcan 2>/dev/null || true
    local ifc
    for ifc in $(ifnames); do
        if ! ip link show dev "$ifc" >/dev/null 2>&1; then
            ip link add dev "$ifc" type vcan || return 1
        fi
        if ! iface_is_up "$ifc"; then
            ip link set up dev "$ifc" || return 1
        fi
        iface_is_up "$ifc" || return 1
    done
}

run_native() {
    say "kernel has CAN: using native $(ifnames | tr '\n' ' ')"
    if (( ${#CMD[@]} == 0 )); then exit 0; fi
    local rc=0
    if (( TIMEOUT > 0 )); then
        timeout --kill-after=10 "$TIMEOUT" "${CMD[@]}" || rc=$?
    else
        "${CMD[@]}" || rc=$?
    fi
    exit "$rc"
}

# ---------------------------------------------------------------- UML mode
find_uml_kernel() {
    local k=${VCAN_UML_KERNEL:-}
    if [[ -z $k && -x $UML_DIR/linux.uml ]]; then
        k=$UML_DIR/linux.uml
    fi
    if [[ -z $k ]]; then
        k=$(command -v linux.uml 2>/dev/null || true)
        [[ -n $k ]] || { [[ -x /usr/bin/linux.uml ]] && k=/usr/bin/linux.uml; }
    fi
    [[ -n $k && -x $k ]] || die "this kernel has no CAN support and user-mode Linux is not installed.
  Install it (Debian/Ubuntu, as root):  apt-get install -y user-mode-linux kmod iproute2 can-utils
  or run on a kernel with CAN/vcan (modprobe vcan)."
    echo "$k"
}

find_uml_modules() {
    local kernel=$1 base=/usr/lib/uml/modules ver dirs
    if [[ -n ${VCAN_UML_MODULES:-} ]]; then echo "$VCAN_UML_MODULES"; return; fi
    [[ $kernel != "$UML_DIR/linux.uml" ]] || base=$UML_DIR/modules
    [[ -d $base ]] || die "UML module directory $base does not exist (package user-mode-linux incomplete?)"
    ver=$(timeout 10 "$kernel" --version </dev/null 2>/dev/null | head -n1 | tr -d '[:space:]' || true)
    if [[ -z $ver || ! -d $base/$ver ]]; then
        ver=$(grep -a -o -m1 'Linux version [^ ]*' "$kernel" 2>/dev/null | head -n1 | awk '{print $3}' || true)
    fi
    if [[ -n $ver && -d $base/$ver ]]; then echo "$base/$ver"; return; fi
    mapfile -t dirs < <(find "$base" -mindepth 1 -maxdepth 1 -type d | sort)
    if (( ${#dirs[@]} == 1 )); then echo "${dirs[0]}"; return; fi
    die "cannot tell which of $base/* matches $kernel (version '${ver:-?}'); set VCAN_UML_MODULES"
}

# Variables passed into UML.
pass_env_names() {
    local n
    for n in PATH HOME USER LOGNAME LANG LC_ALL TERM TMPDIR CI CARGO_HOME RUSTUP_HOME \
             RUSTUP_TOOLCHAIN CARGO_TARGET_DIR CARGO_TERM_COLOR NO_COLOR \
             PYENV_ROOT PYENV_VERSION VIRTUAL_ENV PYTHONPATH ${VCAN_PASS_ENV:-}; do
        echo "$n"
    done
    compgen -e | grep -E '^(RUST_|NEXTEST_|DRIVE_EMU_)' || true
}

write_init() {
    local init=$1 dir=$2 moddir=$3 n
    {
        echo '#!/bin/bash'
        echo '# Generated by vcan-setup.sh: init (pid 1) of the user-mode Linux guest.'
        printf 'DIR=%q\nMODDIR=%q\nNIFACES=%q\nCWD=%q\n' "$dir" "$moddir" "$NIFACES" "$PWD"
        printf 'HOST_STDOUT_TTY=%q\n' "$([[ -t 1 ]] && echo 1 || echo 0)"
        printf 'HOST_TTY_SIZE=%q\n' "$( [[ -t 1 ]] && stty size 2>/dev/null < /dev/tty || true)"
        declare -p CMD
        cat <<'EOF'
export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
OUT=/dev/console ERR=/dev/console
finish() {  # finish STATUS-TEXT
    echo "$1" > "$DIR/status.tmp" && mv -f "$DIR/status.tmp" "$DIR/status"
    sync
    poweroff -f >/dev/null 2>&1
    echo o > /proc/sysrq-trigger 2>/dev/null
    sleep 5; exit 1   # pid 1 exiting panics; the host sees no usable status then
}
fail() { echo "vcan-setup (inside UML): ERROR: $*" > "$ERR"; echo "$*" > "$DIR/error"; finish setup-failed; }

mount -t proc proc /proc || fail "cannot mount /proc"
mount -t sysfs sysfs /sys || fail "cannot mount /sys"
# The guest's own /dev (the host's, seen through hostfs, may lack tty1). Debian's UML
# kernel mounts a devtmpfs there itself (guest only; the host's /dev is untouched).
grep -q '^devtmpfs /dev ' /proc/mounts || mount -t devtmpfs devtmpfs /dev 2>/dev/null
if grep -q '^devtmpfs /dev ' /proc/mounts && [[ -c /dev/console ]]; then
    ln -sfn /proc/self/fd /dev/fd
    ln -sfn /proc/self/fd/0 /dev/stdin
    ln -sfn /proc/self/fd/1 /dev/stdout
    ln -sfn /proc/self/fd/2 /dev/stderr
    mkdir -p /dev/shm /dev/pts
    mount -t tmpfs -o mode=1777 tmpfs /dev/shm 2>/dev/null
    mount -t devpts -o newinstance,ptmxmode=0666 devpts /dev/pts 2>/dev/null && ln -sfn pts/ptmx /dev/ptmx
    [[ -c /dev/tty1 ]] && ERR=/dev/tty1   # con1 = the caller's stderr
fi
stty -opost < "$OUT" 2>/dev/null   # no \n -> \r\n on the way out
[[ $ERR == "$OUT" ]] || stty -opost < "$ERR" 2>/dev/null
exec < /dev/null > "$OUT" 2> "$ERR"
echo "$(cut -d' ' -f1 /proc/uptime)" > "$DIR/boot-uptime"

for m in net/can/can.ko net/can/can-raw.ko drivers/net/can/dev/can-dev.ko drivers/net/can/vcan.ko; do
    [[ -f $MODDIR/kernel/$m ]] || fail "module $MODDIR/kernel/$m missing"
    insmod "$MODDIR/kernel/$m" || fail "insmod $MODDIR/kernel/$m failed"
done
[[ -f $MODDIR/kernel/net/can/can-bcm.ko ]] && { insmod "$MODDIR/kernel/net/can/can-bcm.ko" || true; }
ip link set up dev lo || fail "cannot bring up lo"
for ((i = 0; i < NIFACES; i++)); do
    ip link add dev "vcan$i" type vcan || fail "ip link add dev vcan$i type vcan failed"
    ip link set up dev "vcan$i" || fail "ip link set up dev vcan$i failed"
    ip -o link show dev "vcan$i" | grep -q '[<,]UP[,>]' || fail "vcan$i is not UP"
done
echo "$(cut -d' ' -f1 /proc/uptime)" > "$DIR/ready-uptime"

EOF
        # The caller's environment, safely quoted.
        echo '# --- environment of the caller'
        while read -r n; do
            [[ $n =~ ^[A-Za-z_][A-Za-z0-9_]*$ ]] || continue
            if [[ -v $n ]]; then printf 'export %s=%q\n' "$n" "${!n}"; fi
        done < <(pass_env_names | sort -u)
        cat <<'EOF'
cd "$CWD" || fail "cannot cd to $CWD inside UML"
if [[ $HOST_STDOUT_TTY == 1 ]]; then
    # Interactive caller: keep the console tty (colours, progress bars), sized like theirs.
    [[ -n $HOST_TTY_SIZE ]] && stty rows "${HOST_TTY_SIZE% *}" cols "${HOST_TTY_SIZE#* }" < "$OUT" 2>/dev/null
    "${CMD[@]}"
    rc=$?
else
    # The caller's output is a file or pipe: give the command pipes too, so that it
    # behaves as it would here (no colours, no progress bars), stdout and stderr apart.
    exec 5>&1 6>&2
    exec 7> >(exec cat >&5); p1=$!
    exec 8> >(exec cat >&6); p2=$!
    "${CMD[@]}" >&7 2>&8
    rc=$?
    exec 7>&- 8>&- 5>&- 6>&-
    # Wait for the copies to drain (not forever: a leftover background job may hold a pipe).
    for ((i = 0; i < 100; i++)); do
        kill -0 "$p1" 2>/dev/null || kill -0 "$p2" 2>/dev/null || break
        sleep 0.05
    done
fi
finish "$rc"
EOF
    } > "$init"
    chmod 755 "$init"
}

run_uml() {
    if (( ${#CMD[@]} == 0 )); then
        die "this kernel has no CAN support (socket(AF_CAN) fails), so vcan interfaces cannot be
  created here. Give a COMMAND to run it inside user-mode Linux with vcan0.. up, e.g.
    ./vcan-setup.sh -- cargo nextest run -p e2e
    ./vcan-setup.sh -- sh -c 'candump vcan0 & sleep 1; cansend vcan0 123#DEADBEEF'"
    fi
    local kernel moddir mem tmpdir memdir t0 rc status
    kernel=$(find_uml_kernel) || exit $?
    moddir=$(find_uml_modules "$kernel") || exit $?
    [[ -f $moddir/kernel/drivers/net/can/vcan.ko ]] || die "no vcan.ko under $moddir"
    command -v insmod >/dev/null || die "insmod not found: apt-get install -y kmod"
    command -v ip >/dev/null || die "ip not found: apt-get install -y iproute2"
    mem=${VCAN_UML_MEM:-2G}

    tmpdir=$(mktemp -d "${TMPDIR:-/tmp}/vcan-uml.XXXXXX")
    # shellcheck disable=SC2064
    trap "rm -rf '$tmpdir'" EXIT
    mkdir "$tmpdir/mem"
    write_init "$tmpdir/init" "$tmpdir" "$moddir"

    # UML backs its RAM with an unlinked file in $TMPDIR (default /dev/shm): use /dev/shm
    # only if it is big enough (it is 64M in many containers), else a disk-backed dir.
    local need_kb shm_kb
    need_kb=$(numfmt --from=iec "${mem}" 2>/dev/null || echo $((2 << 30)))
    need_kb=$((need_kb / 1024))
    shm_kb=$(df -Pk /dev/shm 2>/dev/null | awk 'NR == 2 { print $4 }' || true)
    if [[ -n $shm_kb ]] && (( shm_kb > need_kb + 65536 )); then memdir=/dev/shm; else memdir=$tmpdir/mem; fi

    say "no CAN in this kernel: booting user-mode Linux ($(basename "$moddir"), mem=$mem) for $(ifnames | tr '\n' ' ')"
    t0=$(now)
    local -a uml=(env TMPDIR="$memdir" "$kernel" "mem=$mem" root=/dev/root rootfstype=hostfs rootflags=/ rw
                  "init=$tmpdir/init" con=null con0=fd:3,fd:1 con1=fd:4,fd:2 ssl=null
                  quiet loglevel=0 selinux=0)
    (( TIMEOUT == 0 )) || uml=(timeout --kill-after=10 "$TIMEOUT" "${uml[@]}")
    # linux.uml puts itself in its own process group, so a Ctrl-C does not reach it:
    # run it in the background and forward INT/TERM/HUP (SIGTERM shuts it down).
    local uml_pid interrupted=
    "${uml[@]}" </dev/null 3</dev/null 4</dev/null &
    uml_pid=$!
    # shellcheck disable=SC2064
    for sig in INT TERM HUP; do trap "interrupted=$sig; kill -TERM $uml_pid 2>/dev/null" "$sig"; done
    rc=0
    wait "$uml_pid" || rc=$?
    while kill -0 "$uml_pid" 2>/dev/null; do rc=0; wait "$uml_pid" || rc=$?; done
    trap - INT TERM HUP
    [[ -z $interrupted ]] || { echo "$PROG: interrupted (SIG$interrupted): user-mode Linux stopped" >&2; exit 130; }
    local total; total=$(elapsed "$t0")

    if [[ -f $tmpdir/status ]]; then
        status=$(<"$tmpdir/status")
    else
        status=
    fi
    if [[ $status == setup-failed ]]; then
        die "vcan setup inside user-mode Linux failed: $(cat "$tmpdir/error" 2>/dev/null)"
    fi
    if ! [[ $status =~ ^[0-9]+$ ]]; then
        if (( TIMEOUT > 0 )) && (( rc == 124 || rc == 137 )); then
            die "timed out after ${TIMEOUT}s inside user-mode Linux (linux.uml status $rc)"
        fi
        if [[ ! -f $tmpdir/boot-uptime ]]; then
            die "user-mode Linux did not boot or did not start our init (linux.uml exit status $rc, ${total}s).
  On CPUs with AVX-512/AMX state, UML kernels before 7.x cannot boot (\"ptrace set fp regs
  failed, errno = 14\"): run  sudo $0 --install-uml  once.
  Try by hand: $kernel mem=$mem root=/dev/root rootfstype=hostfs rootflags=/ rw init=/bin/sh"
        fi
        die "user-mode Linux stopped without reporting the command's status (linux.uml exit status $rc, ${total}s)"
    fi
    if [[ -f $tmpdir/ready-uptime ]]; then
        say "vcan up $(cat "$tmpdir/ready-uptime")s after UML kernel start; command exited with $status; ${total}s in UML in all"
    fi
    exit "$status"
}

# ---------------------------------------------------------------- --install-uml
# Boot `kernel` with a tiny init that only reports back: does it boot on this CPU?
uml_boots() {
    local kernel=$1 dir rc=0
    dir=$(mktemp -d "${TMPDIR:-/tmp}/vcan-uml-probe.XXXXXX")
    printf '#!/bin/sh\necho booted > %s/booted\nexec /sbin/poweroff -f\n' "$dir" > "$dir/init"
    chmod +x "$dir/init"
    # in a subshell: a kernel that aborts is reported by our log, not by bash's job message
    (timeout --kill-after=5 60 env TMPDIR="$dir" "$kernel" mem=256M root=/dev/root \
        rootfstype=hostfs rootflags=/ rw "init=$dir/init" con=null ssl=null quiet loglevel=0 \
        </dev/null >"$dir/log" 2>&1) 2>/dev/null || rc=$?
    if [[ -f $dir/booted ]]; then rm -rf "$dir"; return 0; fi
    grep -a -m1 -E 'ptrace|panic|failed' "$dir/log" >&2 || true
    rm -rf "$dir"
    return 1
}

install_uml() {
    local k suite=${VCAN_UML_SUITE:-forky} tmp apt
    k=$(command -v linux.uml 2>/dev/null || true)
    if [[ -x $UML_DIR/linux.uml ]] && uml_boots "$UML_DIR/linux.uml"; then
        say "user-mode Linux in $UML_DIR boots here"; exit 0
    fi
    if [[ -n $k ]] && uml_boots "$k"; then
        say "the distribution's user-mode Linux ($k) boots here"; exit 0
    fi
    say "the distribution's user-mode Linux ${k:+($k) }does not boot on this CPU: installing Debian $suite's in $UML_DIR"
    (( $(id -u) == 0 )) || die "--install-uml needs root (it writes $UML_DIR)"
    command -v apt-get >/dev/null && command -v dpkg >/dev/null || die "--install-uml needs apt-get and dpkg (Debian/Ubuntu)"
    command -v patchelf >/dev/null || die "--install-uml needs patchelf: apt-get install -y patchelf"
    tmp=$(mktemp -d "${TMPDIR:-/tmp}/vcan-uml-install.XXXXXX")
    # shellcheck disable=SC2064
    trap "rm -rf '$tmp'" EXIT
    mkdir -p "$tmp/lists/partial" "$tmp/archives/partial" "$tmp/x"
    echo "deb [signed-by=/usr/share/keyrings/debian-archive-keyring.gpg] http://deb.debian.org/debian $suite main" > "$tmp/sources.list"
    apt=(apt-get -q -o "Dir::Etc::SourceList=$tmp/sources.list" -o Dir::Etc::SourceParts=/nonexistent
         -o "Dir::State::Lists=$tmp/lists" -o "Dir::Cache::Archives=$tmp/archives"
         -o APT::Sandbox::User=root)
    "${apt[@]}" update >/dev/null || die "apt-get update of Debian $suite failed"
    (cd "$tmp" && "${apt[@]}" download user-mode-linux libc6 >/dev/null) ||
        die "apt-get download of user-mode-linux and libc6 from Debian $suite failed"
    dpkg -x "$tmp"/user-mode-linux_*.deb "$tmp/x"
    dpkg -x "$tmp"/libc6_*.deb "$tmp/x"
    rm -rf "$UML_DIR.new"
    mkdir -p "$UML_DIR.new/libc" "$UML_DIR.new/modules"
    cp "$tmp/x/usr/bin/linux.uml" "$UML_DIR.new/linux.uml"
    cp -a "$tmp"/x/usr/lib/uml/modules/. "$UML_DIR.new/modules/"
    cp -a "$tmp"/x/usr/lib/x86_64-linux-gnu/. "$UML_DIR.new/libc/"
    # the kernel binary runs with its own C library (newer than this system's); the
    # programs inside UML are this system's, with this system's C library
    patchelf --set-interpreter "$UML_DIR/libc/ld-linux-x86-64.so.2" --set-rpath "$UML_DIR/libc" \
        "$UML_DIR.new/linux.uml"
    rm -rf "$UML_DIR.old"
    [[ ! -e $UML_DIR ]] || mv "$UML_DIR" "$UML_DIR.old"
    mv "$UML_DIR.new" "$UML_DIR"
    rm -rf "$UML_DIR.old"
    uml_boots "$UML_DIR/linux.uml" || die "Debian $suite's user-mode Linux in $UML_DIR does not boot either"
    say "installed $(ls "$UML_DIR/modules") in $UML_DIR; it boots here"
    exit 0
}

# ---------------------------------------------------------------- main
(( INSTALL_UML == 0 )) || install_uml
case "$MODE" in
    native)
        kernel_has_can || die "VCAN_MODE=native but this kernel has no CAN support (socket(AF_CAN) fails)"
        native_setup || die "could not create/bring up $(ifnames | tr '\n' ' ')(needs root: sudo $0 --ifaces $NIFACES)"
        run_native ;;
    uml)
        run_uml ;;
    auto)
        if kernel_has_can; then
            if native_setup; then
                run_native
            fi
            (( ${#CMD[@]} > 0 )) || die "this kernel has CAN but $(ifnames | tr '\n' ' ')could not be created/brought up (needs root and the vcan module: sudo modprobe vcan; sudo $0 --ifaces $NIFACES)"
            say "kernel has CAN but vcan interfaces could not be set up natively: falling back to user-mode Linux"
        fi
        run_uml ;;
    *) echo "$PROG: VCAN_MODE must be auto, native or uml (got '$MODE')" >&2; exit 2 ;;
esac
