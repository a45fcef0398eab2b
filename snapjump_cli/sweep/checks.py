"""The checks every YAML input of snapjump shares (sweep configs, optimize specs): the one-line
:class:`ConfigError` naming the file and the key path, and the checking context that turns a value
into a number, an integer, a boolean or a mapping of known keys, or raises that error.
"""
from __future__ import annotations

import dataclasses
import math
import re
from typing import Any, Mapping

__all__ = ["ConfigError", "CheckContext"]

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_FLOAT_RE = re.compile(rf"^\s*({_NUM})\s*$")
_FRACTION_RE = re.compile(rf"^\s*({_NUM})\s*/\s*({_NUM})\s*$")

class ConfigError(ValueError):
    """A sweep configuration that does not match the schema.

    The message is one line: ``<file>: <key.path>: expected ..., got ...``.
    """

    def __init__(self, source: str, key_path: str, message: str) -> None:
        self.source = source
        self.key_path = key_path
        where = f"{source}: {key_path}: " if key_path else f"{source}: "
        super().__init__(where + message)


# ---- scalar validators ---------------------------------------------------------------------
def _describe(value: Any) -> str:
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return f"the boolean {value}"
    if isinstance(value, (list, tuple)):
        return "a list"
    if isinstance(value, Mapping):
        return "a mapping"
    return f"{value!r}"


class CheckContext:
    """Carries the source name to build errors."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, path: str, expected: str, value: Any = dataclasses.MISSING) -> ConfigError:
        if value is dataclasses.MISSING:
            return ConfigError(self.source, path, expected)
        return ConfigError(self.source, path, f"expected {expected}, got {_describe(value)}")

    def number(self, path: str, value: Any, expected: str = "a finite number") -> float:
        if isinstance(value, bool) or value is None:
            raise self.fail(path, expected, value)
        if isinstance(value, (int, float)):
            x = float(value)
        elif isinstance(value, str) and _FLOAT_RE.match(value):
            x = float(value)
        elif isinstance(value, str) and (m := _FRACTION_RE.match(value)) and float(m.group(2)) != 0.0:
            x = float(m.group(1)) / float(m.group(2))
        else:
            raise self.fail(path, expected, value)
        if not math.isfinite(x):
            raise self.fail(path, expected, value)
        return x

    def positive(self, path: str, value: Any) -> float:
        x = self.number(path, value, "a finite number > 0")
        if x <= 0.0:
            raise self.fail(path, "a finite number > 0", value)
        return x

    def integer(self, path: str, value: Any, minimum: int | None = None, nonzero: bool = False) -> int:
        expected = "an integer" + (f" >= {minimum}" if minimum is not None else "") + (" other than 0" if nonzero else "")
        if isinstance(value, bool) or value is None:
            raise self.fail(path, expected, value)
        if isinstance(value, int):
            n = value
        else:
            try:
                x = self.number(path, value, expected)
            except ConfigError:
                raise self.fail(path, expected, value) from None
            if not float(x).is_integer():
                raise self.fail(path, expected, value)
            n = int(x)
        if minimum is not None and n < minimum:
            raise self.fail(path, expected, value)
        if nonzero and n == 0:
            raise self.fail(path, expected, value)
        return n

    def boolean(self, path: str, value: Any) -> bool:
        if not isinstance(value, bool):
            raise self.fail(path, "true or false", value)
        return value

    def mapping(self, path: str, value: Any, allowed: Mapping[str, str], required: tuple[str, ...] = ()) -> dict:
        if not isinstance(value, Mapping):
            raise self.fail(path, f"a mapping with keys {', '.join(allowed)}", value)
        for k in value:
            if not isinstance(k, str) or k not in allowed:
                kp = f"{path}.{k}" if path else str(k)
                raise ConfigError(self.source, kp, f"unknown key; expected one of: {', '.join(allowed)}")
        for k in required:
            if k not in value:
                kp = f"{path}.{k}" if path else k
                raise ConfigError(self.source, kp, f"missing required key; expected {allowed[k]}")
        return dict(value)
