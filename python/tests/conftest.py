"""Tests of the drive_emu fixture and the examples; they need a CAN bus (vcan0): run them
through ../../vcan-setup.sh where the kernel has no CAN (./test-all.sh does)."""
