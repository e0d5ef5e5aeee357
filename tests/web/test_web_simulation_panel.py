"""The simulation panel (issue 29): Play says that it drops the run going on, and "Put
devices back" takes emulated devices out of the faults an experiment left, audited with
the user, on emulated devices only."""

from __future__ import annotations

from typing import Any

from app.station.emulated import read_device_file
from hw.devices import DeviceKind
from hw.emulation.world import EmulatedWorld
from planner.runner import StartIntention
from tests.support.stations import ROOT, RunningStation
from tests.web.test_web_engineer import post, signed_in

DEVICES = ROOT / "models" / "demo_station.devices.yaml"


def test_play_says_it_drops_the_run_going_on(station: RunningStation) -> None:
    client, _ = signed_in(station)
    live = station.live
    idle = client.get("/simulation/fragments/experiments").text
    assert 'data-confirm="Play E6: robot 2 stops answering above the engine?' in idle
    assert "drops it" not in idle
    live.act(StartIntention(user="engineer", name="assemble_engine")).result(10)
    station.wait(lambda: live.view.state.intentions["assemble_engine"] == "e")
    busy = client.get("/simulation/fragments/experiments").text
    assert 'data-confirm="A run is going (assemble the engine): playing drops it. Play E6' in busy
    assert 'data-testid="run-going"' in busy
    page = client.get("/simulation").text
    assert 'hx-get="/simulation/fragments/experiments"' in page  # live: it follows the run
    assert "hx-confirm" not in page.split('id="simulation-experiments"')[1]


def test_put_back_is_refused_on_a_simulated_world(station: RunningStation) -> None:
    client, token = signed_in(station)
    assert "Put devices back" not in client.get("/simulation").text
    refused = post(client, token, "/simulation/devices/put-back")
    assert refused.status_code == 409 and "only emulated devices" in refused.text


class Emulated:
    """The station's devices, said to be emulated, with put_back recorded."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.put = 0

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    @property
    def kind(self) -> DeviceKind:
        return DeviceKind.EMULATED

    def put_back(self) -> list[str]:
        self.put += 1
        return ["r1", "r2"]


def test_put_back_on_emulated_devices_is_audited_with_the_user(station: RunningStation) -> None:
    client, token = signed_in(station)
    cycle = station.live.running.cycle
    real = cycle.devices
    emulated = Emulated(real)
    cycle.devices = emulated
    try:
        page = client.get("/simulation").text
        assert "Put devices back" in page
        done = post(client, token, "/simulation/devices/put-back")
    finally:
        cycle.devices = real
    assert done.status_code == 200, done.text
    assert emulated.put == 1
    assert "Devices put back where they are, out of their faults: robot 1, robot 2." in done.text
    records = station.audit_records("experiment", "devices put back")
    assert records and records[-1]["user"] == "engineer"
    assert records[-1]["devices"] == "r1, r2"


def test_the_emulated_world_clears_every_fault_and_moves_nothing(station: RunningStation) -> None:
    model = station.live.view.model.station
    devices = read_device_file(str(DEVICES), model)
    controls = {d.name: ("127.0.0.1", 1) for d in devices.devices}
    world = EmulatedWorld(devices, controls, model)
    sent: list[tuple[str, dict[str, Any]]] = []
    world.request = lambda device, request: sent.append((device, request))  # type: ignore[method-assign]
    try:
        names = world.put_back()
    finally:
        world.close()
    kinds = {d.name: d.driver.value for d in devices.devices}
    assert sorted(names) == sorted(n for n, kind in kinds.items() if kind in ("ur", "modbus"))
    ops = {(device, r["op"]) for device, r in sent}
    assert ("r1", "protective_stop") in ops and ("r1", "power") in ops and ("r2", "network") in ops
    assert {"jog", "push", "set"}.isdisjoint(r["op"] for _, r in sent)  # where they are
    modbus = [name for name, kind in kinds.items() if kind == "modbus"]
    assert modbus and all((name, "reset") in ops for name in modbus)
    assert all(r.get("on") is not True for _, r in sent if r["op"] == "protective_stop")
