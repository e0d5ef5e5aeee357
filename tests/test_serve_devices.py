"""`sp serve --devices FILE --emulate`, the demo's command: the station process starts the
emulators, drives them through ur_rtde and Modbus TCP, shows each device's link on the station
page, lets the simulation panel's experiments act on the emulators, and takes its emulators
with it when it is killed."""

from __future__ import annotations

import re
import socket
import subprocess
import time
from pathlib import Path

import httpx

from tests.stations import form_token, sign_in_with_forms
from tests.test_durability import ROOT, Serve

DEVICES = ROOT / "models" / "demo_station.devices.yaml"


def free_block() -> int:
    for block in range(90, 120):
        with socket.socket() as probe:
            try:
                probe.bind((f"127.0.{block}.2", 30004))
            except OSError:
                continue
        return block
    raise RuntimeError("no free loopback block")


def devices_shown(browser: httpx.Client) -> dict[str, bool]:
    page = browser.get("/station").text
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


def test_the_demo_station_runs_on_its_emulators_and_takes_them_along(tmp_path: Path) -> None:
    block = free_block()
    devices = tmp_path / "devices.yaml"
    devices.write_text(DEVICES.read_text().replace("127.0.0.", f"127.0.{block}."))
    serve = Serve(tmp_path / "station.db", "--devices", str(devices), "--emulate")
    try:
        serve.start()
        assert len(emulators_of(block)) == 8  # two UR controllers, six Modbus devices
        with httpx.Client(base_url=serve.url, timeout=10) as browser:
            sign_in_with_forms(browser, "engineer", first=True)
            wait_for(lambda: devices_shown(browser) and all(devices_shown(browser).values()), 30)
            assert set(devices_shown(browser)) == {
                "r1", "r2", "r1_tc", "r2_tc", "r1_cam", "r2_cam", "nr", "plc", "operator_watch",
            }  # fmt: skip
            page = browser.get("/simulation")
            assert page.status_code == 200
            assert "on the emulated devices" in page.text and "simulated world" not in page.text
            assert ">EMU</span>" in page.text and ">SIM</span>" not in page.text
            form = {"experiment": "e5_r2_disconnects_clear", "csrf_token": form_token(page.text)}
            assert browser.post("/simulation/experiment", data=form).status_code in (200, 303)
            wait_for(lambda: devices_shown(browser)["r2"] is False, 30)
            r2_unavailable = r'id="resource-r2"[^>]*class="is-error"'
            wait_for(lambda: re.search(r2_unavailable, browser.get("/station").text), 10)
            assert all(v for k, v in devices_shown(browser).items() if k != "r2")
    finally:
        serve.kill() if serve.process and serve.process.poll() is None else None
    wait_for(lambda: not emulators_of(block), 10)  # killed with -9: its emulators end too
