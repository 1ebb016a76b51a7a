"""Tests of the drive_emu fixture and the examples. The fixture's tests run on vcan0 where it
exists (through ../../vcan-setup.sh where the kernel has no CAN: ./test-all.sh does) and over
socketcand where it does not (emulator/tests/socketcand_python.rs runs them so on the host);
the examples take a CAN interface and need vcan0."""
