"""The Modbus devices' logic as pure state machines (no sockets, no clock): the register
maps as documented, each device's behaviour at its deadlines, faults, and properties over
random command schedules."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hw.modbus.driver import LIMITS, plan_reads
from hw.modbus.emulator.camera import CAMERA, Camera
from hw.modbus.emulator.connector import Connector, LockFault
from hw.modbus.emulator.kinds import KINDS
from hw.modbus.emulator.logic import DeviceLogic, Shots
from hw.modbus.emulator.nutrunner import NUTRUNNER, Nutrunner
from hw.modbus.emulator.tracker import Tracker
from hw.modbus.maps import register_map
from hw.modbus.registers import Kind, Point, Table, decode, encode, markdown
from tests.support.paths import REPOSITORY

FAST = {"spin_up": 0.5, "tighten": 2.0, "stop": 0.5}


def command(device: DeviceLogic, now: float, **values: bool) -> None:
    """A client writes coils at `now` (the emulator steps before and after a write)."""
    device.step(now)
    for name, value in values.items():
        device.write(device.register_map.point(name), int(value))
    device.step(now)


def flags(device: DeviceLogic, *names: str) -> tuple[bool, ...]:
    return tuple(bool(device[name]) for name in names)


# -- register maps -------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_each_table_is_addressed_from_0_without_gaps_and_heartbeat_is_input_register_0(
    kind: str,
) -> None:
    registers = register_map(kind)
    for table in Table:
        addresses = [r.point.address for r in registers.table(table)]
        assert addresses == list(range(len(addresses))), (kind, table)
    assert registers.point("heartbeat") == Point(Table.INPUT_REGISTER, 0)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_status_words_name_discrete_inputs_and_start_consistent(kind: str) -> None:
    device = KINDS[kind](0.0)
    for status in (r for r in device.register_map if r.kind is Kind.BITS):
        expected = sum(device[code] << bit for bit, code in enumerate(status.codes))
        assert device[status.name] == expected
        for code in status.codes:
            assert device.register_map.point(code).table is Table.DISCRETE_INPUT


@given(st.data())
def test_encode_then_decode_gives_the_value_back_for_every_register(data: st.DataObject) -> None:
    kind = data.draw(st.sampled_from(sorted(KINDS)))
    register = data.draw(st.sampled_from(register_map(kind).registers))
    if register.kind is Kind.BOOL:
        value: object = data.draw(st.booleans())
    elif register.kind is Kind.ENUMERATION:
        value = data.draw(st.sampled_from(register.codes))
    else:
        low, high = register.range()
        raw = data.draw(st.integers(round(low / register.scale), round(high / register.scale)))
        value = raw * register.scale if register.scale != 1 else raw
    word = encode(register, value)
    assert 0 <= word <= 0xFFFF
    back = decode(register, word)
    if isinstance(value, float):
        assert back == pytest.approx(value, abs=register.scale / 2)
    else:
        assert back == value


def test_encode_refuses_out_of_range_unless_raw() -> None:
    torque = NUTRUNNER["torque"]
    with pytest.raises(ValueError, match="outside the documented range"):
        encode(torque, 250.0)
    assert encode(torque, 5000, raw=True) == 5000
    with pytest.raises(ValueError, match="does not fit"):
        encode(torque, 70000, raw=True)
    assert encode(CAMERA["y"], -120.0) == 0x10000 - 1200
    assert decode(CAMERA["y"], 0x10000 - 1200) == pytest.approx(-120.0)


# -- nutrunner -----------------------------------------------------------------------------------


def test_nutrunner_spins_up_tightens_to_torque_and_goes_idle_at_its_deadlines() -> None:
    nr = Nutrunner(0.0, FAST)
    command(nr, 1.0, set_idle=False, run_forward=True)
    nr.step(1.49)
    assert flags(nr, "is_idle", "is_running") == (True, False)
    nr.step(1.5)
    assert flags(nr, "is_idle", "is_running", "torque_reached") == (False, True, False)
    nr.step(2.5)
    assert nr.value("torque") == pytest.approx(12.5)  # half-way up to 25 Nm
    nr.step(3.5)
    assert flags(nr, "torque_reached", "nok") == (True, False)
    assert nr["torque"] == nr["target_torque"] == 250
    assert nr["status"] == 0b0110
    command(nr, 4.0, set_idle=True, run_forward=False)
    nr.step(4.49)
    assert flags(nr, "is_running", "torque_reached") == (True, True)
    nr.step(4.5)
    assert flags(nr, "is_idle", "is_running", "torque_reached", "nok") == (
        True,
        False,
        False,
        False,
    )
    assert nr["torque"] == 0 and nr["status"] == 0b0001


def test_nutrunner_nok_strikes_the_next_run_only_and_stop_clears_it() -> None:
    nr = Nutrunner(0.0, FAST)
    nr.nok_fault = Shots(times=1)
    command(nr, 0.0, set_idle=False, run_forward=True)
    nr.step(3.0)
    assert flags(nr, "torque_reached", "nok", "is_running") == (False, True, True)
    assert nr["torque"] == 150  # 60 % of 25 Nm
    command(nr, 3.0, set_idle=True, run_forward=False)
    nr.step(4.0)
    assert flags(nr, "nok", "is_idle") == (False, True)
    command(nr, 4.0, set_idle=False, run_forward=True)
    nr.step(7.0)
    assert flags(nr, "torque_reached", "nok") == (True, False)


def test_nutrunner_tightens_only_while_held_down_on_a_bolt() -> None:
    nr = Nutrunner(0.0, FAST)
    nr.engaged = False
    command(nr, 0.0, set_idle=False, run_forward=True)
    nr.step(0.5)
    nr.step(10.0)  # spinning in the air: no torque however long
    assert flags(nr, "is_running", "torque_reached", "nok") == (True, False, False)
    assert nr["torque"] == 0
    nr.engaged = True
    nr.step(11.0)
    assert not flags(nr, "torque_reached")[0]  # the tightening starts when it is held down
    nr.step(12.0)
    assert flags(nr, "torque_reached") == (True,)


def test_nutrunner_told_to_idle_before_spinning_up_never_runs() -> None:
    nr = Nutrunner(0.0, FAST)
    command(nr, 0.0, set_idle=False, run_forward=True)
    command(nr, 0.2, set_idle=True, run_forward=False)
    nr.step(5.0)
    assert flags(nr, "is_idle", "is_running", "torque_reached") == (True, False, False)


def test_nutrunner_target_torque_from_its_holding_register() -> None:
    nr = Nutrunner(0.0, FAST)
    nr.write(NUTRUNNER.point("target_torque"), 123)
    command(nr, 0.0, set_idle=False, run_forward=True)
    nr.step(3.0)
    assert nr["torque"] == 123


# -- connector -----------------------------------------------------------------------------------


def test_connector_locks_and_unlocks_with_both_sensors_changing_together() -> None:
    tc = Connector(0.0, {"lock": 1.0, "unlock": 0.5})
    command(tc, 0.0, lock=True, unlock=False)
    tc.step(0.99)
    assert flags(tc, "connected", "not_connected") == (False, True)
    tc.step(1.0)
    assert flags(tc, "connected", "not_connected", "failure") == (True, False, False)
    assert tc["status"] == 0b001
    command(tc, 2.0, lock=False, unlock=True)
    tc.step(2.49)
    assert flags(tc, "connected", "not_connected") == (True, False)
    tc.step(2.5)
    assert flags(tc, "connected", "not_connected") == (False, True)


def test_connector_lock_that_never_completes_until_a_reset() -> None:
    tc = Connector(0.0)
    tc.fail_locks(Shots(always=True), LockFault.NEVER)
    command(tc, 0.0, lock=True, unlock=False)
    tc.step(100.0)
    assert flags(tc, "connected", "not_connected", "failure") == (False, True, False)
    tc.reset()
    tc.step(100.1)
    assert flags(tc, "connected", "not_connected") == (True, False)


def test_connector_release_that_never_completes_until_the_fault_ends() -> None:
    tc = Connector(0.0, {"lock": 1.0, "unlock": 0.5})
    command(tc, 0.0, lock=True, unlock=False)
    tc.step(1.0)
    tc.fail_unlocks(Shots(always=True))
    command(tc, 2.0, lock=False, unlock=True)
    tc.step(50.0)
    assert flags(tc, "connected", "not_connected") == (True, False)
    tc.fail_unlocks(Shots(times=0))
    tc.step(50.1)
    assert flags(tc, "connected", "not_connected") == (False, True)


def test_connector_lock_hanging_on_a_fault_completes_when_the_fault_ends() -> None:
    tc = Connector(0.0)
    tc.fail_locks(Shots(always=True), LockFault.NEVER)
    command(tc, 0.0, lock=True, unlock=False)
    tc.step(10.0)
    assert flags(tc, "connected") == (False,)
    tc.fail_locks(Shots(times=0), LockFault.NEVER)
    tc.step(10.1)
    assert flags(tc, "connected") == (True,)


def test_connector_failure_bit_blocks_locking_until_the_reset_coil_rises() -> None:
    tc = Connector(0.0)
    tc.fail_locks(Shots(times=1), LockFault.FAILURE)
    command(tc, 0.0, lock=True, unlock=False)
    tc.step(5.0)
    assert flags(tc, "connected", "not_connected", "failure") == (False, True, True)
    assert tc["status"] == 0b110
    command(tc, 6.0, reset=True)
    assert not tc["failure"]
    tc.step(7.0)  # the lock command still stands: it locks now
    assert flags(tc, "connected", "failure") == (True, False)


def test_stuck_sensor_shows_its_value_and_reset_shows_the_truth() -> None:
    tc = Connector(0.0)
    tc.stick("connected", False)
    command(tc, 0.0, lock=True, unlock=False)
    tc.step(2.0)
    assert flags(tc, "connected", "not_connected") == (False, False)
    assert tc["status"] == 0b000
    assert tc.faults()["stuck"] == {"connected": False}
    tc.reset()
    assert flags(tc, "connected", "not_connected") == (True, False)
    assert tc["status"] == 0b001
    with pytest.raises(ValueError, match="command"):
        tc.stick("lock", True)


# -- camera --------------------------------------------------------------------------------------


def test_camera_locates_the_scene_pose_and_clears_when_the_trigger_falls() -> None:
    cam = Camera(0.0, {"process": 0.8, "clear": 0.2})
    cam.see((100.0, -250.5, 30.0, 0.1, -3.0, 1.5))
    command(cam, 0.0, trigger=True)
    assert flags(cam, "busy", "located") == (True, False)
    cam.step(0.8)
    assert flags(cam, "busy", "located", "missed") == (False, True, False)
    pose = [cam.value(n) for n in ("x", "y", "z", "rx", "ry", "rz")]
    assert pose == pytest.approx([100.0, -250.5, 30.0, 0.1, -3.0, 1.5])
    assert cam["scans"] == 1
    cam.step(10.0)  # the result stays while triggered
    assert cam["located"]
    command(cam, 10.0, trigger=False)
    cam.step(10.19)
    assert cam["located"]
    cam.step(10.2)
    assert flags(cam, "located", "missed") == (False, False)
    assert cam["x"] == cam["y"] == 0


def test_camera_misses_the_next_n_scans() -> None:
    cam = Camera(0.0, {"process": 0.5, "clear": 0.1})
    cam.miss_fault = Shots(times=2)
    t = 0.0
    results = []
    for _ in range(3):
        command(cam, t, trigger=True)
        cam.step(t + 0.5)
        results.append(flags(cam, "located", "missed"))
        command(cam, t + 0.5, trigger=False)
        t += 1.0
    assert results == [(False, True), (False, True), (True, False)]


# -- tracker -------------------------------------------------------------------------------------


def test_tracker_values_change_only_when_set() -> None:
    plc = Tracker(0.0)
    assert plc.value("bp1.state") == "empty" and plc.value("agv.engine") is True
    plc.set("bp1.state", "placed")
    plc.set("mir.docked", False)
    plc.step(1000.0)
    assert plc.value("bp1.state") == "placed" and plc["bp1.state"] == 1
    assert plc.value("mir.docked") is False
    with pytest.raises(ValueError, match="one of empty, placed, tightened"):
        plc.set("bp2.state", "lost")
    plc.set("bp2.state", 7, raw=True)
    assert plc["bp2.state"] == 7
    assert plc["heartbeat"] == 10000 & 0xFFFF


# -- properties ----------------------------------------------------------------------------------

COILS = {kind: [r.name for r in register_map(kind).table(Table.COIL)] for kind in KINDS}


@st.composite
def schedules(draw: st.DrawFn) -> tuple[str, list[tuple[float, str, bool]], list[float], float]:
    kind = draw(st.sampled_from(sorted(k for k in KINDS if COILS[k])))
    times = st.floats(0.0, 10.0, allow_nan=False).map(lambda t: round(t, 3))
    writes = draw(
        st.lists(st.tuples(times, st.sampled_from(COILS[kind]), st.booleans()), max_size=12)
    )
    writes.sort(key=lambda w: w[0])
    extra = sorted(draw(st.lists(times, max_size=30)))
    return kind, writes, extra, 12.0


@settings(max_examples=150, deadline=None)
@given(schedules())
def test_how_often_a_device_steps_does_not_change_what_it_does(
    schedule: tuple[str, list[tuple[float, str, bool]], list[float], float],
) -> None:
    """Stepping only at the writes gives the registers that stepping in between gives: the
    transitions happen at their own deadlines (the emulator steps on requests only)."""
    kind, writes, extra, end = schedule
    coarse, fine = KINDS[kind](0.0), KINDS[kind](0.0)
    for device, steps in ((coarse, []), (fine, extra)):
        pending = sorted(
            [(t, 1, name, v) for t, name, v in writes] + [(t, 0, "", False) for t in steps]
        )
        for t, is_write, name, value in pending:
            if is_write:
                command(device, t, **{name: value})
            else:
                device.step(t)
        device.step(end)
    assert coarse.raw == fine.raw


@settings(max_examples=100, deadline=None)
@given(schedules())
def test_the_status_word_always_repeats_the_discrete_inputs(
    schedule: tuple[str, list[tuple[float, str, bool]], list[float], float],
) -> None:
    kind, writes, extra, end = schedule
    device = KINDS[kind](0.0)
    status = [r for r in device.register_map if r.kind is Kind.BITS]
    events = sorted([(t, name, v) for t, name, v in writes] + [(t, "", False) for t in extra])
    for t, name, value in [*events, (end, "", False)]:
        if name:
            command(device, t, **{name: value})
        else:
            device.step(t)
        for word in status:
            expected = sum(device[code] << bit for bit, code in enumerate(word.codes))
            assert device[word.name] == expected


@given(
    st.lists(
        st.builds(Point, st.sampled_from(list(Table)), st.integers(0, 5000)),
        min_size=1,
        max_size=40,
    ),
    st.one_of(st.none(), st.integers(0, 20)),
)
def test_read_plan_covers_every_point_within_the_limits(
    points: list[Point], max_gap: int | None
) -> None:
    plan = plan_reads(points, max_gap)
    for point in points:
        assert any(
            r.table is point.table and r.address <= point.address < r.address + r.count
            for r in plan
        )
    for request in plan:
        assert 1 <= request.count <= LIMITS[request.table.is_bit]
    for table in Table:
        addresses = sorted({p.address for p in points if p.table is table})
        requests = [r for r in plan if r.table is table]
        assert len(requests) <= len(addresses)
        if addresses and max_gap is None and addresses[-1] - addresses[0] < LIMITS[table.is_bit]:
            assert len(requests) == 1


def test_read_plan_of_a_whole_device_is_one_request_per_table() -> None:
    plan = plan_reads([r.point for r in NUTRUNNER])
    assert [(r.table, r.address, r.count) for r in plan] == [
        (Table.COIL, 0, 2),
        (Table.DISCRETE_INPUT, 0, 4),
        (Table.HOLDING_REGISTER, 0, 1),
        (Table.INPUT_REGISTER, 0, 3),
    ]


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_the_documentation_shows_each_register_map_as_it_is(kind: str) -> None:
    document = REPOSITORY / "docs" / "modbus_devices.md"
    assert markdown(register_map(kind)) in document.read_text()
