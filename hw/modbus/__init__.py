"""Modbus TCP devices: their register maps, the station's driver and adapter, and emulators.

- `registers`: tables, points and documented registers; `maps`: each device kind's map
  (docs/modbus_devices.md);
- `driver`: the station's side, polling points and writing level commands on one background
  loop that all drivers share (`loop`); `adapter`: bits and words to the model's values;
- `emulator/`: each kind's logic and the process that serves it.
"""
