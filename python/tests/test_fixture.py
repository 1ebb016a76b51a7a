"""The drive_emu fixture: ready line, EDS for the same drive, live and exit statistics, and
python canopen's documented reset + wait_for_bootup() seeing the boot-up."""
import configparser
import struct
import time

import canopen
import pytest

from drive_emu_testing import DriveEmu, find_binary

TIMEOUT = 60  # generous: user-mode Linux is slow; nothing here measures time


def connect(emu):
    """On the drive's bus: its vcan interface, or socketcand where there is none."""
    network = canopen.Network()
    network.connect(**emu.can_args)
    return network


def wait_for(pred, what, timeout=TIMEOUT):
    deadline = time.monotonic() + timeout
    while not pred():
        assert time.monotonic() < deadline, f"timeout waiting for {what}"
        time.sleep(0.02)


@pytest.mark.drive_emu(node_id=21, preset="cnc1", set=["kv_per_s=20", "backlash_mm=0.04"])
def test_ready_line_eds_and_live_statistics(drive_emu):
    ready = drive_emu.ready
    assert ready["event"] == "ready"
    if drive_emu.transport == "socketcand":
        assert ready["iface"] is None
        assert ready["socketcand"]["port"] == drive_emu.socketcand[1] > 0
    else:
        assert ready["iface"] == drive_emu.iface
    assert ready["nodes"] == [
        {"node_id": 21, "preset": "cnc1", "worn": "backlash 0.04 mm", "eds": None, "objects_base": "0x2000",
         "profile": None, "quirks": []}
    ]
    cfg = configparser.ConfigParser()
    cfg.optionxform = str
    cfg.read(drive_emu.eds_path)
    assert cfg["DeviceComissioning"]["NodeID"] == "21"
    network = connect(drive_emu)
    try:
        node = canopen.RemoteNode(drive_emu.node_id, drive_emu.eds_path)
        network.add_node(node)
        node.sdo.RESPONSE_TIMEOUT = 5.0
        # the EDS says what the drive has: --set values included
        for index, want in ((0x2007, 20.0), (0x2000, 0.04)):
            got = struct.unpack("<f", node.sdo.upload(index, 0))[0]
            assert got == pytest.approx(want, rel=1e-6)
            # and python canopen reads that default from the EDS (REAL32 as a decimal)
            default = node.object_dictionary[index].default
            assert default is not None, f"0x{index:04X}: python canopen read no default"
            assert default == pytest.approx(got, rel=1e-6)
        first = drive_emu.statistics(node)
        assert set(first) >= {"ticks", "overruns", "lateness_p99_us"}
        wait_for(lambda: drive_emu.statistics(node)["ticks"] > first["ticks"],
                 "the loop's tick count (0x2100:1) to grow")
    finally:
        network.disconnect()


@pytest.mark.parametrize("command", ["RESET COMMUNICATION", "RESET"])
@pytest.mark.drive_emu(node_id=22)
def test_reset_then_wait_for_bootup_sees_the_boot_up(drive_emu, command):
    network = connect(drive_emu)
    try:
        node = canopen.RemoteNode(drive_emu.node_id, drive_emu.eds_path)
        network.add_node(node)
        for _ in range(3):
            node.nmt.state = command
            node.nmt.wait_for_bootup(TIMEOUT)  # raises on timeout
            assert node.nmt.state == "PRE-OPERATIONAL"
    finally:
        network.disconnect()


@pytest.mark.drive_emu(node_id=23, lockstep=True, sync_period_us=10000)
def test_lockstep_drive_boots_without_sync(drive_emu):
    # a master waits for the boot-up before it sends SYNC: the boot delay of a lock-step
    # drive passes on the wall clock
    network = connect(drive_emu)
    try:
        node = canopen.RemoteNode(drive_emu.node_id, drive_emu.eds_path)
        network.add_node(node)
        node.nmt.state = "RESET COMMUNICATION"
        node.nmt.wait_for_bootup(TIMEOUT)
    finally:
        network.disconnect()


def test_exit_statistics_after_sigterm(request):
    iface = request.config.getoption("--drive-emu-iface") or "vcan0"
    emu = DriveEmu(iface=iface, node_id=24, binary=request.config.getoption("--drive-emu-bin"),
                   socketcand=request.config.getoption("--drive-emu-socketcand"))
    with emu:
        assert emu.alive()
        time.sleep(0.5)
    assert emu.returncode == 0
    stats = emu.exit_statistics
    assert stats["ticks"] > 0
    assert {"overruns", "lateness_p50_us", "lateness_p99_us", "lateness_max_us"} <= set(stats)


def test_a_bad_preset_is_a_clear_error(request):
    emu = DriveEmu(preset="cnc9", node_id=25, binary=request.config.getoption("--drive-emu-bin"))
    with pytest.raises(Exception) as err:
        emu.start()
    assert "cnc9" in str(err.value)


def test_binary_lookup_names_the_fix(monkeypatch):
    monkeypatch.setenv("DRIVE_EMU_BIN", "/nonexistent/drive-emu")
    with pytest.raises(Exception) as err:
        find_binary()
    assert "/nonexistent/drive-emu" in str(err.value)
