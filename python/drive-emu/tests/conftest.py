"""Shared fixtures of the drive_emu module's tests (host only: no CAN needed).

`drive_emu_bin`: the `drive-emu` command-line program the module is compared with:
$DRIVE_EMU_BIN, else `drive-emu` on the PATH; a missing binary fails the test that needs it
(build it with `cargo build --release -p drive-emu`; ./test-all.sh sets DRIVE_EMU_BIN).
"""
import json
import os
import shutil
import subprocess

import pytest


@pytest.fixture(scope="session")
def drive_emu_bin():
    path = os.environ.get("DRIVE_EMU_BIN") or shutil.which("drive-emu")
    if not path or not os.access(path, os.X_OK):
        pytest.fail("the drive-emu binary is needed to compare the module with the CLI: set "
                    "DRIVE_EMU_BIN (cargo build --release -p drive-emu; "
                    "target/release/drive-emu) or put drive-emu on the PATH", pytrace=False)
    return path


@pytest.fixture(scope="session")
def cli(drive_emu_bin):
    """Run `drive-emu ARGS...`; returns the CompletedProcess (text), failing on a non-zero
    exit unless `check=False`."""
    def run(*args, check=True, cwd=None):
        done = subprocess.run([drive_emu_bin, *map(str, args)], capture_output=True, text=True,
                              timeout=600, cwd=cwd)
        if check and done.returncode != 0:
            pytest.fail(f"drive-emu {' '.join(map(str, args))}: exit {done.returncode}\n"
                        f"{done.stderr}", pytrace=False)
        return done

    run.json = lambda *args, **kw: json.loads(run(*args, **kw).stdout)
    return run
