"""The fixture without kernel CAN: the drive served over socketcand, chosen explicitly or
because the interface does not exist, reached with python-can's socketcand interface."""
import time

import can
import canopen

from drive_emu_testing import DriveEmu, interface_exists

TIMEOUT = 60  # generous: a loaded machine; nothing here measures time


def test_a_missing_interface_means_socketcand(request):
    assert not interface_exists("nosuchcan9")
    emu = DriveEmu(iface="nosuchcan9", node_id=31,
                   binary=request.config.getoption("--drive-emu-bin"))
    with emu:
        assert emu.transport == "socketcand"
        host, port = emu.socketcand
        assert host == "127.0.0.1" and port > 0
        assert emu.can_args == {"interface": "socketcand", "host": host, "port": port,
                                "channel": "can0"}
        assert emu.ready["iface"] is None
        # python-can alone: an NMT reset of node 31, and its boot-up on the bus
        with can.Bus(**emu.can_args) as bus:
            bus.send(can.Message(arbitration_id=0, data=[0x82, 31], is_extended_id=False))
            while True:
                msg = bus.recv(TIMEOUT)
                assert msg is not None, "no boot-up within the timeout"
                if msg.arbitration_id == 0x700 + 31:
                    assert list(msg.data) == [0]
                    break
    assert emu.returncode == 0


def test_two_masters_share_the_socketcand_bus(request):
    emu = DriveEmu(node_id=32, socketcand="127.0.0.1:0",
                   binary=request.config.getoption("--drive-emu-bin"))
    with emu:
        assert emu.transport == "socketcand"
        a, b = canopen.Network(), canopen.Network()
        a.connect(**emu.can_args)
        b.connect(**emu.can_args)
        try:
            heard = []
            b.subscribe(0x123, lambda cob_id, data, t: heard.append(bytes(data)))
            node = canopen.RemoteNode(32, emu.eds_path)
            a.add_node(node)
            node.sdo.RESPONSE_TIMEOUT = 5.0
            # what one master sends, the other hears (a CAN bus), and the drive answers it
            a.send_message(0x123, b"\x01\x02")
            assert int.from_bytes(node.sdo.upload(0x1000, 0), "little") == 0x00020192
            deadline = time.monotonic() + TIMEOUT
            while not heard:
                assert time.monotonic() < deadline, "B did not hear A"
                time.sleep(0.01)
            assert heard == [b"\x01\x02"]
            # the loop statistics over SDO: published every 256 ticks, so they grow
            while emu.statistics(node)["ticks"] == 0:
                assert time.monotonic() < deadline, "0x2100:1 (ticks) stayed 0"
                time.sleep(0.05)
        finally:
            a.disconnect()
            b.disconnect()
