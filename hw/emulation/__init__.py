"""What the emulated devices share: their control channel and how they are started.

Every emulator (a UR controller, a Modbus device) runs as its own process.  Besides its
device protocol it listens on a control channel, where tests, `sp emulate`, scenarios and the
simulation panel make it fail on demand or change its world (`hw.emulation.control`).
"""
