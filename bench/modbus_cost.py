"""How much the Modbus drivers cost: CPU of this process and poll latency, with the
station's seven Modbus devices emulated in another process.

    python -m bench.modbus_cost [--seconds 10] [--period 0.05] [--host 127.0.2.30]

Every driver polls every point of its device's map (one request per table) and watches its
heartbeat; the emulator runs in its own process, so only the drivers' cost is counted.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time
from collections.abc import Sequence

from hw.emulator_kit.process import start
from hw.modbus.driver import ModbusDriver
from hw.modbus.maps import register_map

STATION = (
    ("nutrunner", "nr"),
    ("connector", "r1_tc"),
    ("connector", "r2_tc"),
    ("camera", "r1_cam"),
    ("camera", "r2_cam"),
    ("tracker", "plc"),
    ("connector", "spare_tc"),
)


def measure(seconds: float, period: float, host: str) -> dict[str, float]:
    args = [a for kind, name in STATION for a in ("--device", f"{kind}:{name}:{host}:0")]
    emulator = start("hw.modbus.emulator.server", *args)
    drivers = []
    try:
        for kind, name in STATION:
            registers = register_map(kind)
            points = [r.point for r in registers]
            heartbeat = registers.point("heartbeat")
            port = emulator.ports[name]
            drivers.append(
                ModbusDriver(name, host, port, 1, points, poll_period=period, heartbeat=heartbeat)
            )
        for driver in drivers:
            driver.start()
        time.sleep(1.0)
        latencies: list[float] = []
        began, before = time.monotonic(), resource.getrusage(resource.RUSAGE_SELF)
        while time.monotonic() - began < seconds:
            time.sleep(0.1)
            for driver in drivers:
                status = driver.status()
                if status.connected and status.latency_ms is not None:
                    latencies.append(status.latency_ms)
        after, ended = resource.getrusage(resource.RUSAGE_SELF), time.monotonic()
    finally:
        for driver in drivers:
            driver.close()
        emulator.stop()
    used = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    latencies.sort()
    return {
        "cpu_percent": 100.0 * used / (ended - began),
        "latency_median_ms": statistics.median(latencies),
        "latency_p95_ms": latencies[int(0.95 * (len(latencies) - 1))],
        "latency_max_ms": latencies[-1],
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.modbus_cost", description=__doc__)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--period", type=float, default=0.05)
    parser.add_argument("--host", default="127.0.2.30")
    args = parser.parse_args(argv)
    result = measure(args.seconds, args.period, args.host)
    print(
        f"{len(STATION)} Modbus devices every {args.period * 1000:g} ms: "
        f"driver CPU {result['cpu_percent']:.1f} % of one core; poll latency (all tables) "
        f"median {result['latency_median_ms']:.1f} ms, p95 {result['latency_p95_ms']:.1f} ms, "
        f"max {result['latency_max_ms']:.1f} ms"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
