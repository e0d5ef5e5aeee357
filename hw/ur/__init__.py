"""Universal Robots: an emulated controller (`hw.ur.controller`) and the station's driver.

The emulator speaks enough RTDE, dashboard and script-port protocol for the unmodified ur_rtde
clients; the driver (`hw.ur.driver.URDriver`) runs those clients in a supervised child process.
See docs/ur_emulator.md.
"""
