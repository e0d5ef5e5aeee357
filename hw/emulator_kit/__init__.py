"""What every emulator shares, below both protocols: the control channel on which tests,
`sp emulate`, scenarios and the simulation panel make it fail or change its world, and how
an emulator process is started and stopped."""
