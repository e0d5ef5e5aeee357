"""An emulated UR controller: RTDE (30004), the dashboard (29999) and the script ports on one
address, moving its joints toward commanded targets over time, faults on a control channel
(`python -m hw.ur.emulator.server --help`, docs/ur_emulator.md)."""
