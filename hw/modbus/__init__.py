"""Modbus TCP devices: their register maps, emulators of their logic, and the station's driver.

- `registers`: tables, points and documented registers (`docs/modbus_devices.md`);
- `logic` and one module per device kind (`nutrunner`, `connector`, `camera`, `tracker`):
  the device's behaviour as a clock-free state machine over its registers;
- `emulator`: a process serving devices over Modbus TCP with faults on a control channel
  (`python -m hw.modbus.emulator --help`), whose operations are in `operations`;
- `driver`: the station's side, polling points and writing level commands on one
  background loop that all drivers share (`loop`);
- `measure`: what the drivers cost (`python -m hw.modbus.measure`).
"""
