"""The device benchmark runs end to end on the emulated demo station, briefly, and leaves
nothing behind (python -m bench.devices does the same for longer)."""

from __future__ import annotations

import math
import os
import re

from bench.devices import children, measure, report
from hw.modbus import loop as modbus_loop


def test_a_short_device_benchmark_reports_every_row_with_sane_numbers() -> None:
    before = set(children(os.getpid()))
    measured = measure(seconds=2.0, rounds=2, cuts=1)
    for samples in (measured.motion, measured.coil, measured.robot_read, measured.plc_read):
        assert len(samples) == 2
        assert all(0.0 < s < 5.0 for s in samples)
    assert set(measured.cut) == {"r1", "r2", "r1_tc", "r2_tc", "r1_cam", "r2_cam", "nr"}
    assert all(len(samples) == 1 and samples[0] > 0.0 for samples in measured.cut.values())
    loop = measured.loop
    assert len(loop.durations) >= 10
    assert all(math.isfinite(p) and p > 0 for p in loop.periods)
    assert {"ur_rtde child r1 (process)", "ur_rtde child r2 (process)"} <= {
        what for what, _ in loop.cpu
    }
    assert all(math.isfinite(p) and p >= 0 for p in loop.cpu.values()), loop.cpu
    text = report(measured, 2.0, 2, 1)
    rows = ("command to motion, UR", "command to coil, Modbus", "period between round starts")
    for row in (*rows, "cut noticed, r1", "cut noticed, nr"):
        assert re.search(rf"\| {re.escape(row)}.*\| \d+ \| [\d.]+ \|", text), row
    assert "device layer, station side" in text
    # everything stopped: no emulator, driver child or Modbus loop left
    assert not modbus_loop.running()
    left = {
        pid for pid, cmdline in children(os.getpid()).items() if "resource_tracker" not in cmdline
    }
    assert left <= before
