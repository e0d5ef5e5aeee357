"""Emulated Modbus TCP devices: each kind's logic as a clock-free state machine over its
register map (`hw.modbus.maps`), served by one process per device with faults on a control
channel (`python -m hw.modbus.emulator.server.server --help`, docs/modbus_devices.md)."""
