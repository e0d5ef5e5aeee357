"""Universal Robots: the station's driver and adapter, and an emulated controller.

- `driver`: runs the unmodified ur_rtde clients in a supervised child process
  (`driver_child`), one `sample` per reading;
- `adapter`: joints to the model's named poses, named poses to moveJ;
- `emulator/`: enough RTDE, dashboard and script-port protocol for those clients
  (docs/ur_emulator.md).
"""
