"""The RTDE wire format (port 30004), as a UR controller speaks it: framing and recipes.

A message is `size:uint16, type:uint8, payload`, big-endian, the size counting the 3-byte
header.  Clients negotiate protocol version 2, ask the controller version, set up one output
recipe (a frequency and comma-joined variable names; the answer is a recipe id and the type of
each name) and any number of input recipes, then start the stream of data packages.  Nothing
here does I/O: bytes in, values out, and a `Recipe` precompiles the `struct` for one recipe so
that packing a data package is one call.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

HEADER = struct.Struct(">HB")

REQUEST_PROTOCOL_VERSION = ord("V")
GET_URCONTROL_VERSION = ord("v")
TEXT_MESSAGE = ord("M")  # never sent by the emulator; listed with the protocol's other types
DATA_PACKAGE = ord("U")
SETUP_OUTPUTS = ord("O")
SETUP_INPUTS = ord("I")
START = ord("S")
PAUSE = ord("P")

PROTOCOL_VERSION = 2
MAX_MESSAGE = 0xFFFF

NOT_FOUND = "NOT_FOUND"
IN_USE = "IN_USE"

# The RTDE types and how each one packs (big-endian).
TYPE_FORMATS: Mapping[str, str] = {
    "DOUBLE": "d",
    "UINT32": "I",
    "INT32": "i",
    "UINT64": "Q",
    "UINT8": "B",
    "BOOL": "?",
    "VECTOR3D": "3d",
    "VECTOR6D": "6d",
    "VECTOR6INT32": "6i",
    "VECTOR6UINT32": "6I",
}
VECTOR_SIZES: Mapping[str, int] = {
    "VECTOR3D": 3,
    "VECTOR6D": 6,
    "VECTOR6INT32": 6,
    "VECTOR6UINT32": 6,
}


def _registers(prefix: str, kind: str, numbers: Iterable[int]) -> dict[str, str]:
    return {f"{prefix}{n}": kind for n in numbers}


def _input_registers() -> dict[str, str]:
    return {
        "input_bit_registers0_to_31": "UINT32",
        "input_bit_registers32_to_63": "UINT32",
        **_registers("input_bit_register_", "BOOL", range(64, 128)),
        **_registers("input_int_register_", "INT32", range(48)),
        **_registers("input_double_register_", "DOUBLE", range(48)),
    }


_V6 = "VECTOR6D"
OUTPUTS: Mapping[str, str] = {
    "timestamp": "DOUBLE",
    **{
        name: _V6
        for name in [
            "target_q",
            "target_qd",
            "target_qdd",
            "target_current",
            "target_moment",
            "actual_q",
            "actual_qd",
            "actual_current",
            "joint_control_output",
            "actual_TCP_pose",
            "actual_TCP_speed",
            "actual_TCP_force",
            "target_TCP_pose",
            "target_TCP_speed",
            "joint_temperatures",
            "actual_joint_voltage",
            "payload_inertia",
            "ft_raw_wrench",
            "actual_current_window",
        ]
    },
    "actual_digital_input_bits": "UINT64",
    "actual_execution_time": "DOUBLE",
    "robot_mode": "INT32",
    "joint_mode": "VECTOR6INT32",
    "safety_mode": "INT32",
    "safety_status": "INT32",
    "actual_tool_accelerometer": "VECTOR3D",
    "speed_scaling": "DOUBLE",
    "target_speed_fraction": "DOUBLE",
    "actual_momentum": "DOUBLE",
    "actual_main_voltage": "DOUBLE",
    "actual_robot_voltage": "DOUBLE",
    "actual_robot_current": "DOUBLE",
    "actual_digital_output_bits": "UINT64",
    "runtime_state": "UINT32",
    "elbow_position": "VECTOR3D",
    "elbow_velocity": "VECTOR3D",
    "robot_status_bits": "UINT32",
    "safety_status_bits": "UINT32",
    "analog_io_types": "UINT32",
    "standard_analog_input0": "DOUBLE",
    "standard_analog_input1": "DOUBLE",
    "standard_analog_output0": "DOUBLE",
    "standard_analog_output1": "DOUBLE",
    "io_current": "DOUBLE",
    "euromap67_input_bits": "UINT32",
    "euromap67_output_bits": "UINT32",
    "euromap67_24V_voltage": "DOUBLE",
    "euromap67_24V_current": "DOUBLE",
    "tool_mode": "UINT32",
    "tool_analog_input_types": "UINT32",
    "tool_analog_input0": "DOUBLE",
    "tool_analog_input1": "DOUBLE",
    "tool_output_voltage": "INT32",
    "tool_output_current": "DOUBLE",
    "tool_temperature": "DOUBLE",
    "tcp_force_scalar": "DOUBLE",
    "tool_output_mode": "UINT8",
    "tool_digital_output0_mode": "UINT8",
    "tool_digital_output1_mode": "UINT8",
    "payload": "DOUBLE",
    "payload_cog": "VECTOR3D",
    "script_control_line": "UINT32",
    "joint_position_deviation_ratio": "DOUBLE",
    "collision_detection_ratio": "DOUBLE",
    "output_bit_registers0_to_31": "UINT32",
    "output_bit_registers32_to_63": "UINT32",
    **_registers("output_bit_register_", "BOOL", range(64, 128)),
    **_registers("output_int_register_", "INT32", range(48)),
    **_registers("output_double_register_", "DOUBLE", range(48)),
    **_input_registers(),
}
"""Every output variable a CB3 / e-Series controller knows, with its RTDE type."""

INPUTS: Mapping[str, str] = {
    "speed_slider_mask": "UINT32",
    "speed_slider_fraction": "DOUBLE",
    "standard_digital_output_mask": "UINT8",
    "standard_digital_output": "UINT8",
    "configurable_digital_output_mask": "UINT8",
    "configurable_digital_output": "UINT8",
    "tool_digital_output_mask": "UINT8",
    "tool_digital_output": "UINT8",
    "standard_analog_output_mask": "UINT8",
    "standard_analog_output_type": "UINT8",
    "standard_analog_output_0": "DOUBLE",
    "standard_analog_output_1": "DOUBLE",
    "external_force_torque": "VECTOR6D",
    **_input_registers(),
}
"""Every input variable a client may write, with its RTDE type."""


class WireError(ValueError):
    """Bytes that are not a well-formed RTDE message."""


@dataclass(frozen=True, slots=True)
class Message:
    kind: int
    payload: bytes


def frame(kind: int, payload: bytes = b"") -> bytes:
    """One message: header and payload."""
    size = HEADER.size + len(payload)
    if size > MAX_MESSAGE:
        raise WireError(f"an RTDE message holds at most {MAX_MESSAGE} bytes, not {size}")
    return HEADER.pack(size, kind) + payload


def split(buffer: bytearray) -> list[Message]:
    """Takes every complete message off the front of `buffer` (which keeps the rest)."""
    messages = []
    while len(buffer) >= HEADER.size:
        size, kind = HEADER.unpack_from(buffer)
        if size < HEADER.size:
            raise WireError(f"message size {size} is smaller than its header")
        if len(buffer) < size:
            break
        messages.append(Message(kind, bytes(buffer[HEADER.size : size])))
        del buffer[:size]
    return messages


def protocol_version(payload: bytes) -> int:
    if len(payload) != 2:
        raise WireError("a protocol version request carries one uint16")
    return int(struct.unpack(">H", payload)[0])


def version_answer(accepted: bool) -> bytes:
    return frame(REQUEST_PROTOCOL_VERSION, bytes([1 if accepted else 0]))


def controller_version_answer(major: int, minor: int, bugfix: int, build: int) -> bytes:
    return frame(GET_URCONTROL_VERSION, struct.pack(">IIII", major, minor, bugfix, build))


def _names(text: bytes) -> list[str]:
    try:
        decoded = text.decode("ascii")
    except UnicodeDecodeError:
        raise WireError("variable names must be ASCII") from None
    return [name.strip() for name in decoded.split(",") if name.strip()]


def output_setup(payload: bytes) -> tuple[float, list[str]]:
    """(frequency, names) of a protocol-2 output setup request."""
    if len(payload) < 8:
        raise WireError("an output setup starts with a double frequency")
    (frequency,) = struct.unpack_from(">d", payload)
    return float(frequency), _names(payload[8:])


def input_setup(payload: bytes) -> list[str]:
    return _names(payload)


def setup_answer(kind: int, recipe_id: int, types: Sequence[str]) -> bytes:
    return frame(kind, bytes([recipe_id]) + ",".join(types).encode("ascii"))


def success_answer(kind: int, ok: bool = True) -> bytes:
    return frame(kind, bytes([1 if ok else 0]))


def output_types(names: Sequence[str]) -> list[str]:
    return [OUTPUTS.get(name, NOT_FOUND) for name in names]


@dataclass(frozen=True)
class Recipe:
    """A set-up recipe: its id, names and types, and the precompiled struct of its package."""

    recipe_id: int
    names: tuple[str, ...]
    types: tuple[str, ...]
    codec: struct.Struct = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        unknown = [t for t in self.types if t not in TYPE_FORMATS]
        if unknown:
            raise WireError(f"no RTDE type {unknown[0]!r}")
        fmt = ">B" + "".join(TYPE_FORMATS[t] for t in self.types)
        object.__setattr__(self, "codec", struct.Struct(fmt))

    @classmethod
    def of(cls, recipe_id: int, names: Sequence[str], table: Mapping[str, str]) -> Recipe:
        return cls(recipe_id, tuple(names), tuple(table[name] for name in names))

    def pack(self, values: Mapping[str, Any]) -> bytes:
        """A data package with the values of this recipe's names (vectors as sequences)."""
        flat: list[Any] = [self.recipe_id]
        for name, kind in zip(self.names, self.types, strict=True):
            if kind in VECTOR_SIZES:
                flat.extend(values[name])
            else:
                flat.append(values[name])
        return frame(DATA_PACKAGE, self.codec.pack(*flat))

    def unpack(self, payload: bytes) -> dict[str, Any]:
        """The values of a data package for this recipe (vectors as tuples)."""
        if len(payload) != self.codec.size:
            raise WireError(
                f"recipe {self.recipe_id} packs {self.codec.size} bytes, not {len(payload)}"
            )
        flat = self.codec.unpack(payload)
        if flat[0] != self.recipe_id:
            raise WireError(f"package of recipe {flat[0]} read as recipe {self.recipe_id}")
        values: dict[str, Any] = {}
        at = 1
        for name, kind in zip(self.names, self.types, strict=True):
            size = VECTOR_SIZES.get(kind, 0)
            if size:
                values[name] = tuple(flat[at : at + size])
                at += size
            else:
                values[name] = flat[at]
                at += 1
        return values


def package_recipe_id(payload: bytes) -> int:
    if not payload:
        raise WireError("an empty data package")
    return payload[0]
