"""An emulated UR controller: RTDE (30004), the dashboard (29999) and the script ports on one
address, moving its joints toward commanded targets over time, faults on a control channel
(`python -m hw.ur.emulator.server --help`, docs/ur_emulator.md).

`controller` is the controller itself (modes, safety, program, registers, arm), with no I/O;
`server` is the process around it: its ports, connections, network faults and cycle.
"""
