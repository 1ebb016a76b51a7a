"""pytest plugin: the `drive_emu` fixture (a running drive-emu) and its options."""

import os

import pytest

from . import DriveEmu


def pytest_addoption(parser):
    g = parser.getgroup("drive-emu")
    g.addoption("--drive-emu-iface", default=None,
                help="CAN interface for drive-emu (default: $DRIVE_EMU_VCAN or vcan0)")
    g.addoption("--drive-emu-socketcand", default=None, metavar="HOST:PORT",
                help="serve the bus over socketcand on HOST:PORT (port 0: any free one) "
                     "instead of a CAN interface (default: $DRIVE_EMU_SOCKETCAND, else "
                     "socketcand on 127.0.0.1:0 where the interface does not exist)")
    g.addoption("--drive-emu-bin", default=None,
                help="drive-emu binary (default: $DRIVE_EMU_BIN or drive-emu on the PATH)")
    g.addoption("--drive-emu-node", type=int, default=5, help="node ID (default 5)")
    g.addoption("--drive-emu-preset", default="cnc1", help="axis preset (default cnc1)")
    g.addoption("--drive-emu-set", action="append", default=[], metavar="KEY=VALUE",
                help="override a preset key (repeatable)")


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "drive_emu(**kwargs): arguments for this test's drive-emu (node_id, preset, set, "
        "lockstep, sync_period_us, boot_delay_ms, extra_args)")


@pytest.fixture
def drive_emu(request):
    """A drive-emu on the bus for this test: yields a started `DriveEmu` (attributes iface,
    node_id, eds_path, ready, can_args (for `network.connect(**drive_emu.can_args)`: on
    vcan or, where there is none, over socketcand); method statistics(node)); stops it with SIGTERM afterwards and
    fails the test if it did not exit cleanly with statistics (then in `exit_statistics`)."""
    opt = request.config.getoption
    kwargs = dict(
        iface=opt("--drive-emu-iface") or os.environ.get("DRIVE_EMU_VCAN") or "vcan0",
        binary=opt("--drive-emu-bin"),
        node_id=opt("--drive-emu-node"),
        preset=opt("--drive-emu-preset"),
        set=list(opt("--drive-emu-set")),
        socketcand=opt("--drive-emu-socketcand"),
    )
    marker = request.node.get_closest_marker("drive_emu")
    if marker is not None:
        kwargs.update(marker.kwargs)
    emu = DriveEmu(**kwargs)
    emu.start()
    try:
        yield emu
    finally:
        emu.stop(check=True)
