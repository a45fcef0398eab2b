"""The checks every YAML input of snapjump shares (sweep configs, optimize specs): reading the file
(:func:`read_yaml`: bounded in size, duplicate keys refused), the one-line :class:`ConfigError`
naming the file and the key path, and the checking context that turns a value into a number, an
integer, a boolean or a mapping of known keys, or raises that error.
"""
from __future__ import annotations

import dataclasses
import logging
import math
import os
import re
import sys
from pathlib import Path
from typing import Any, Mapping

__all__ = ["ConfigError", "CheckContext", "warn_if_radians", "read_yaml", "YAML_MAX_BYTES", "JOBS_PER_CORE", "max_jobs", "jobs_error"]

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
        if x != 0.0 and abs(x) < sys.float_info.min:  # subnormal: no setting means that, and it loses digits
            raise ConfigError(self.source, path, f"expected {expected}, got {value!r}, a subnormal number (below "
                                                 f"{sys.float_info.min:.4g}): a typo in the exponent?")
        return x

    def positive(self, path: str, value: Any) -> float:
        x = self.number(path, value, "a finite number > 0")
        if x <= 0.0:
            raise self.fail(path, "a finite number > 0", value)
        return x

    def integer(self, path: str, value: Any, minimum: int | None = None, nonzero: bool = False,
                maximum: int | None = None) -> int:
        if minimum is not None and maximum is not None:
            expected = f"an integer >= {minimum} and <= {maximum}"
        else:
            expected = "an integer" + (f" >= {minimum}" if minimum is not None else "") + \
                (f" <= {maximum}" if maximum is not None else "")
        expected += " other than 0" if nonzero else ""
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
        if (minimum is not None and n < minimum) or (maximum is not None and n > maximum):
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


log = logging.getLogger(__name__)


def warn_if_radians(source: str, path: str, values: Any) -> bool:
    """Warn (naming the key) when every angle given for a field in degrees is at most 2 pi, as
    radians would be; returns whether it warned. (Such shallow caps are legal, so it is not an
    error: their designs are usually recorded as ``invalid_geometry``.)"""
    vals = [float(v) for v in values]
    if not vals or not all(0.0 < v <= 2.0 * math.pi for v in vals):
        return False
    shown = ", ".join(f"{v:g}" for v in vals[:4]) + (", ..." if len(vals) > 4 else "")
    deg = ", ".join(f"{math.degrees(v):.4g}" for v in vals[:4]) + (", ..." if len(vals) > 4 else "")
    log.warning("%s: %s: %s look like radians, but this angle is in degrees (in degrees they would be %s); "
                "convert them if they are radians", source, path, shown, deg)
    return True


# ---- reading a YAML file -------------------------------------------------------------------
#: Largest YAML file read (a sweep config or an optimize spec; parsing 1 MB of YAML takes seconds):
#: long lists of designs belong in a CSV or parquet file (``points: designs.csv``), read much faster.
#: The paper grid written as 4800 inline points takes 0.37 MB.
YAML_MAX_BYTES = 1024 * 1024


def _loader() -> type:
    import yaml

    return getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml when built with it: ~10x faster


def _key_text(node: Any) -> str | None:
    import yaml

    return str(node.value) if isinstance(node, yaml.ScalarNode) else None


def _check_duplicates(source: str, root: Any) -> None:
    """Refuse a document with a mapping key given twice, naming the key path and both lines (the
    first such key in the file). Shared (aliased) nodes are visited once."""
    import yaml

    seen: set[int] = set()
    stack = [(root, "")]
    found: list[tuple[int, str, int]] = []  # (line of the second, key path, line of the first)
    while stack:
        node, path = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            lines: dict[tuple[str, str], int] = {}
            for key, value in node.value:
                text = _key_text(key)
                if text is None or key.tag == "tag:yaml.org,2002:merge":
                    continue
                kp = f"{path}.{text}" if path else text
                line = key.start_mark.line + 1
                if (key.tag, text) in lines:
                    found.append((line, kp, lines[(key.tag, text)]))
                else:
                    lines[(key.tag, text)] = line
                stack.append((value, kp))
        elif isinstance(node, yaml.SequenceNode):
            stack.extend((item, f"{path}[{j}]") for j, item in enumerate(node.value))
    if found:
        line, kp, first = min(found)
        raise ConfigError(source, kp, f"duplicate key (lines {first} and {line}); give it once")


def regular_input(source: str, path: str | Path, key: str = "") -> None:
    """Refuse a path that is not a regular file (:func:`snapjump_cli.files.check_readable`) as a
    :class:`ConfigError`; a missing file is left to the reader (its own message)."""
    from snapjump_cli.files import check_readable

    if not os.path.exists(path):
        return

    class _Refused(Exception):
        pass

    try:
        check_readable(path, _Refused, "a regular file")
    except _Refused as e:
        if os.path.isdir(path) and not key:
            raise ConfigError(source, "", "expected a YAML file, got a directory") from None
        raise ConfigError(source, key, str(e)) from None


def read_yaml(path: str | Path) -> Any:
    """Read a YAML file (a sweep config or an optimisation spec) into plain data.

    Safe YAML only; a mapping key given twice is an error (not "the last one wins"), and so is a
    file larger than :data:`YAML_MAX_BYTES` (refused before it is parsed).

    Parameters
    ----------
    path
        The file; its name (``str(path)``) is the source named in error messages.

    Returns
    -------
    Any
        The document as plain data (``None`` for an empty file).

    Raises
    ------
    ConfigError
        The file is missing, a directory, unreadable, too large, not valid YAML, or has a
        duplicate key (naming the key path and both lines).
    """
    import yaml

    source = str(path)
    regular_input(source, path)  # a FIFO or a device would block the read, or never end
    try:
        with open(path, "rb") as fh:
            raw = fh.read(YAML_MAX_BYTES + 1)
    except FileNotFoundError:
        raise ConfigError(source, "", "file not found") from None
    except IsADirectoryError:
        raise ConfigError(source, "", "expected a YAML file, got a directory") from None
    except OSError as e:
        raise ConfigError(source, "", f"cannot read the file ({e})") from None
    if len(raw) > YAML_MAX_BYTES:
        raise ConfigError(source, "", f"larger than {YAML_MAX_BYTES // (1024 * 1024)} MB; a long list of designs "
                                      f"belongs in a CSV or parquet file (points: FILE), read much faster")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(source, "", f"cannot read the file ({e})") from None
    loader = _loader()(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _check_duplicates(source, node)
        return loader.construct_document(node)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise ConfigError(source, "", f"YAML syntax error{where}: {problem}") from None
    finally:
        loader.dispose()


# ---- the number of worker processes ---------------------------------------------------------
#: Most worker processes per CPU core (``-j``, ``n_jobs``): each loads the solver (~0.3 GB); more
#: than a few per core only adds memory and start-up time, and a typo (``-j 100000``) would
#: exhaust the machine.
JOBS_PER_CORE = 4


def max_jobs() -> int:
    """The largest ``-j`` / ``n_jobs`` accepted on this machine: :data:`JOBS_PER_CORE` per core."""
    return JOBS_PER_CORE * (os.cpu_count() or 1)


def jobs_error(n: object) -> str:
    """Why ``n`` is not a valid number of worker processes (``""``: it is). Valid: ``1`` to
    :func:`max_jobs`, or ``-1`` (every core) down to minus the number of cores (joblib: ``-2``
    = every core but one)."""
    cores = os.cpu_count() or 1
    if isinstance(n, int) and not isinstance(n, bool) and (1 <= n <= max_jobs() or -cores <= n <= -1):
        return ""
    return (f"expected 1 to {max_jobs()} ({JOBS_PER_CORE} per core on this machine) or -1 (every core; "
            f"down to -{cores}), got {n!r}")
