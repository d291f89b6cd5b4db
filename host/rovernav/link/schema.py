"""Hand-written base classes for the generated messages (messages_gen.py).

The generated module only declares fields; packing, range checks and unpacking live
here, once, so the generator stays small.
"""

from __future__ import annotations

import dataclasses
import struct
from typing import Any, ClassVar

# type -> (min, max)
_RANGES = {
    "u8": (0, 0xFF),
    "i8": (-0x80, 0x7F),
    "u16": (0, 0xFFFF),
    "i16": (-0x8000, 0x7FFF),
    "u32": (0, 0xFFFFFFFF),
    "i32": (-0x80000000, 0x7FFFFFFF),
}


@dataclasses.dataclass(frozen=True)
class FieldSpec:
    """One field of a message: name, wire type, array length (0 = scalar), unit, meaning."""

    name: str
    type: str
    count: int
    unit: str
    doc: str

    @property
    def limits(self) -> tuple[int, int]:
        return _RANGES[self.type]


@dataclasses.dataclass(frozen=True)
class ParamSpec:
    """A parameter set by CONFIG: id, name, unit, default and inclusive limits, and its scale:
    the wire's integer is the working value times `scale` (the name's _x100, _x1000, _permille;
    1 for the rest)."""

    id: int
    name: str
    unit: str
    default: int
    min: int
    max: int
    doc: str
    scale: int = 1

    def to_value(self, raw: int) -> float:
        """The working value of the wire's integer `raw` (pid_kp_x100 = 3000: 30.0)."""
        return raw / self.scale

    def to_raw(self, value: float) -> int:
        """The wire's integer for the working value `value`, rounded (not checked: see check)."""
        return round(value * self.scale)

    def check(self, value: int) -> int:
        """Return value if it is allowed, else raise ValueError naming the parameter."""
        if not isinstance(value, int) or isinstance(value, bool):
            raise ValueError(f"parameter {self.name}: {value!r} is not an integer")
        if not self.min <= value <= self.max:
            raise ValueError(f"parameter {self.name}: {value} outside [{self.min}, {self.max}] ({self.unit})")
        return value


class Message:
    """Base of every generated message class."""

    ID: ClassVar[int]
    NAME: ClassVar[str]
    DIRECTION: ClassVar[str]
    STRUCT: ClassVar[struct.Struct]
    FIELDS: ClassVar[tuple[FieldSpec, ...]]

    def values(self) -> list[int]:
        """The field values in wire order, arrays flattened; ValueError names a bad field."""
        out: list[int] = []
        for f in self.FIELDS:
            value: Any = getattr(self, f.name)
            items = list(value) if f.count else [value]
            if f.count and len(items) != f.count:
                raise ValueError(f"{self.NAME}.{f.name}: needs {f.count} values, got {len(items)}")
            lo, hi = f.limits
            for item in items:
                if not isinstance(item, int) or isinstance(item, bool) or not lo <= item <= hi:
                    raise ValueError(
                        f"{self.NAME}.{f.name}: {item!r} is not an integer in [{lo}, {hi}] ({f.unit or f.type})"
                    )
            out.extend(items)
        return out

    def pack(self) -> bytes:
        """The payload bytes (little-endian)."""
        return self.STRUCT.pack(*self.values())

    @classmethod
    def unpack(cls, payload: bytes) -> Message:
        """Decode a payload; ValueError if its length is not this message's size."""
        if len(payload) != cls.STRUCT.size:
            raise ValueError(f"{cls.NAME}: payload of {len(payload)} bytes, expected {cls.STRUCT.size}")
        flat = cls.STRUCT.unpack(payload)
        kwargs: dict[str, Any] = {}
        i = 0
        for f in cls.FIELDS:
            if f.count:
                kwargs[f.name] = tuple(flat[i : i + f.count])
                i += f.count
            else:
                kwargs[f.name] = flat[i]
                i += 1
        return cls(**kwargs)  # type: ignore[call-arg]

    def to_dict(self) -> dict[str, Any]:
        return {f.name: (list(getattr(self, f.name)) if f.count else getattr(self, f.name)) for f in self.FIELDS}
