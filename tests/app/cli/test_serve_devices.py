"""`sp serve --devices FILE --emulate`, the demo's command: the station process starts the
emulators, drives them through ur_rtde and Modbus TCP, shows each device's link on the station
page, lets the simulation panel's experiments act on the emulators (the operator finishing E6
from a watch in Chromium), and takes its emulators with it when it is killed."""

from __future__ import annotations

import re
import subprocess
import time
from pathlib import Path
from typing import Any

import httpx

from hw.ur.emulator.launch import free_block, on_block
from tests.app.station.test_durability import ROOT, Serve
from tests.browser.test_browser_operator import WATCH, operate, sign_in_first_time
from tests.support.stations import form_token, sign_in_with_forms

DEVICES = ROOT / "models" / "demo_station.devices.yaml"


def devices_shown(browser: httpx.Client) -> dict[str, bool]:
    page = browser.get("/station/details").text
    found = re.findall(r'data-device="([^"]+)" data-connected="(true|false)"', page)
    return {name: connected == "true" for name, connected in found}


def wait_for(check: object, limit: float) -> None:
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        if check():  # type: ignore[operator]
            return
        time.sleep(0.5)
    raise AssertionError(f"not within {limit} s")


def emulators_of(block: int) -> list[str]:
    ps = subprocess.run(
        ["ps", "-ww", "-eo", "pid,args"], capture_output=True, text=True, check=True
    )
    return [line for line in ps.stdout.splitlines() if f"127.0.{block}." in line]


def test_the_demo_station_runs_on_its_emulators_and_takes_them_along(
    tmp_path: Path, browser: Any
) -> None:
    """The README's walk-through on emulated devices: E6 played from the simulation panel cuts
    r2's network on its emulator, and the operator finishes it from a watch in Chromium."""
    block = free_block(range(90, 120))
    devices = tmp_path / "devices.yaml"
    devices.write_text(on_block(DEVICES.read_text(), block))
    serve = Serve(tmp_path / "station.db", "--devices", str(devices), "--emulate")
    watch = browser.new_context(viewport=WATCH, has_touch=True, is_mobile=True).new_page()
    watch.set_default_timeout(15_000)
    try:
        serve.start()
        assert len(emulators_of(block)) == 8  # two UR controllers, six Modbus devices
        with httpx.Client(base_url=serve.url, timeout=10) as engineer:
            sign_in_with_forms(engineer, "engineer", first=True)
            wait_for(lambda: devices_shown(engineer) and all(devices_shown(engineer).values()), 30)
            assert set(devices_shown(engineer)) == {
                "r1", "r2", "r1_tc", "r2_tc", "r1_cam", "r2_cam", "nr", "plc", "operator_watch",
            }  # fmt: skip
            # a station starting up is no fault: no alarm while its devices first answered
            assert [a["key"] for a in engineer.get("/api/alarms").json()] == []
            page = engineer.get("/simulation")
            assert page.status_code == 200
            assert "on the emulated devices" in page.text and "simulated world" not in page.text
            assert ">EMU</span>" in page.text and ">SIM</span>" not in page.text
            sign_in_first_time(watch, serve.url, "operator")

            def state() -> dict[str, Any]:
                answer: dict[str, Any] = engineer.get("/api/station").json()
                return answer

            start = state()["variables"]
            form = {
                "experiment": "e6_r2_disconnects_above_engine",
                "csrf_token": form_token(page.text),
            }
            assert engineer.post("/simulation/experiment", data=form).status_code in (200, 303)
            r2_cut: list[bool] = []

            def watch_r2(kind: str, title: str, card: Any) -> None:
                if kind == "instruction":  # by then r2 has stopped answering on its emulator
                    r2_cut.append(devices_shown(engineer)["r2"] is False)
                    r2_error = r'id="resource-r2"[^>]*class="is-error"'
                    r2_cut.append(bool(re.search(r2_error, engineer.get("/station/details").text)))

            done = lambda: state()["intentions"].get("tighten_bolts") == "f"  # noqa: E731
            seen = operate(watch, done, watch_r2, seconds=180)
            assert ("instruction", "Move robot 2 home by hand") in seen, seen
            assert r2_cut == [True, True]
            # the emulated nutrunner tightens only while a robot's emulated joints stand at a
            # bolt pair: tightened bolts mean the robots moved there on ur_rtde's moveJ
            end = state()["variables"]
            assert start["bp1.state"] != "tightened"
            assert all(end[f"bp{k}.state"] == "tightened" for k in range(1, 5))
            assert end["r2.pos"] == "home"
            assert all(v for k, v in devices_shown(engineer).items() if k != "r2")
    finally:
        watch.context.close()
        serve.kill() if serve.process and serve.process.poll() is None else None
    wait_for(lambda: not emulators_of(block), 10)  # killed with -9: its emulators end too
