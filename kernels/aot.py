"""Ahead-of-time compiled kernels: start-up without numba's run-time initialisation.

A process that calls a cached ``@njit`` kernel first pays for numba's own target (its lowering
registries, ~0.4 s, which also import ``scipy.linalg`` for a BLAS check) and for rebuilding each
kernel from the cache (~20 ms each). :func:`build` (``make install`` runs it) compiles the kernels
the solver calls (:data:`snapjump_kernels.calls.KERNELS`) into one extension module,
``snapjump_kernels/_aot*.so``, with ``numba.pycc`` for this machine's CPU and with the signatures
the solver actually uses (collected by solving a few scenes first). :mod:`snapjump_kernels.calls`,
the module the solver imports its kernels from, then hands out the compiled functions, and a
``snapjump curve`` process neither imports numba nor initialises its target.

Each exported function is a thin wrapper that calls the ``@njit`` kernel, so the kernel keeps its
own options (``error_model``, ``fastmath``) and the machine code is that of the JIT: the answers
are bit-identical (``tests/unit/test_aot.py``). A call whose argument types differ from the
compiled signatures (checked exactly: dtype, dimensions, contiguity, writability) goes to the
dispatcher, imported on first use. The extension is used only when it was built from the current
kernel sources (a hash of them is stored beside it) on this CPU (model and feature flags) and
``SNAPJUMP_NO_AOT`` is not set; otherwise
everything runs through the JIT as before. The kernel modules themselves are never modified: a
kernel calling another still calls its dispatcher.
"""
from __future__ import annotations

import functools
import hashlib
import importlib
import json
import os
import sys
from pathlib import Path
from typing import Any, Callable

from snapjump_kernels import source_hash

HERE = Path(__file__).resolve().parent
MODULE = "_aot"
STAMP = HERE / "_aot.sha256"  # the kernel sources' hash the extension was built from
EXPORTS = HERE / "_aot_exports.json"  # kernel module -> names compiled (not a .py: it would change the hash)


def _arg_spec(t: Any) -> list | None:
    """A JSON-able description of one numba argument type, or None if the check below cannot
    express it (the signature then stays JIT-only)."""
    from numba.core import types

    if isinstance(t, types.Array) and isinstance(t.dtype, (types.Float, types.Integer, types.Boolean)):
        return ["array", str(t.dtype), t.ndim, t.layout, bool(t.mutable)]
    if isinstance(t, types.Boolean):
        return ["bool"]
    if isinstance(t, types.Integer):
        return ["int"]
    if isinstance(t, types.Float):
        return ["float"]
    return None


def _arg_check(spec: list) -> Callable[[Any], bool]:
    """Whether a Python argument is exactly of the type ``spec`` describes (dtype, dimensions,
    contiguity, writability for arrays): only then is the compiled function called."""
    import numpy as np

    kind = spec[0]
    if kind == "array":
        dt, nd, layout, mutable = np.dtype(spec[1]), spec[2], spec[3], spec[4]
        flag = {"C": "C_CONTIGUOUS", "F": "F_CONTIGUOUS"}.get(layout)

        def ok(a: Any) -> bool:
            return (type(a) is np.ndarray and a.dtype == dt and a.ndim == nd
                    and (flag is None or a.flags[flag]) and (not mutable or a.flags.writeable))

        return ok
    if kind == "bool":
        return lambda a: isinstance(a, (bool, np.bool_))
    if kind == "int":
        return lambda a: isinstance(a, (int, np.integer)) and not isinstance(a, (bool, np.bool_))
    return lambda a: isinstance(a, (float, np.floating))


def _dispatch(variants: list[tuple[Callable, list[Callable[[Any], bool]]]], jit: Any) -> Callable:
    """The kernel as callers see it: the first compiled variant whose argument types match
    exactly, else the JIT dispatcher."""

    def call(*args):
        for compiled, checks in variants:
            if len(args) == len(checks) and all(c(a) for c, a in zip(checks, args)):
                return compiled(*args)
        return jit(*args)

    call.__name__ = getattr(jit, "__name__", "kernel")
    call.__doc__ = getattr(jit, "__doc__", None)
    call.jit = jit  # what a mismatch calls (the dispatcher, imported on first use)
    return call


def cpu_fields() -> dict[str, str]:
    """The first processor's entries of ``/proc/cpuinfo`` (empty where there is none)."""
    fields: dict[str, str] = {}
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if not line.strip():
                    break  # the first processor is enough
                key, _, value = line.partition(":")
                fields[key.strip()] = value.strip()
    except OSError:
        pass
    return fields


def cpu_signature() -> str:
    """What identifies this CPU for the compiled code (built for the host CPU, it may use
    instructions another CPU lacks): the model name and feature flags of ``/proc/cpuinfo``, else
    ``platform.processor()``, with ``platform.machine()``."""
    import platform

    fields = cpu_fields()
    text = "|".join([fields.get("model name", platform.processor()), fields.get("flags", ""), platform.machine()])
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@functools.lru_cache(maxsize=1)
def _table() -> tuple[dict[str, dict[str, list]], Any]:
    """The export table and the extension, read once per process, if built from the current
    sources on this CPU and ``SNAPJUMP_NO_AOT`` is unset; else ``({}, None)``. Imports no numba."""
    if os.environ.get("SNAPJUMP_NO_AOT", "") not in ("", "0"):
        return {}, None
    try:
        if STAMP.read_text().strip() != source_hash():
            return {}, None
        table = json.loads(EXPORTS.read_text())
        if table.get("cpu") != cpu_signature():  # built on another CPU (a shared install)
            return {}, None
        exports = table["kernels"]
        ext = importlib.import_module(f"{__package__}.{MODULE}")
    except (OSError, ImportError, ValueError, KeyError):
        return {}, None
    return exports, ext


class _LazyJit:
    """The dispatcher of ``snapjump_kernels.<module>.<name>``, imported (with numba) on first use."""

    def __init__(self, module: str, name: str) -> None:
        self.module, self.name, self._f = module, name, None

    def __call__(self, *args):
        if self._f is None:
            self._f = getattr(importlib.import_module(f"{__package__}.{self.module}"), self.name)
        return self._f(*args)


def kernel(module: str, name: str) -> Callable:
    """``snapjump_kernels.<module>.<name>`` as the solver calls it: the compiled variants first
    (exact argument match), the JIT dispatcher otherwise; the plain dispatcher when there is no
    matching extension (:mod:`snapjump_kernels.calls` builds its names with this)."""
    exports, ext = _table()
    if ext is None:
        return getattr(importlib.import_module(f"{__package__}.{module}"), name)
    variants = exports.get(module, {}).get(name)
    if not variants:  # not compiled ahead of time: the dispatcher, but only when first called
        return _LazyJit(module, name)
    compiled = [(getattr(ext, v["export"]), [_arg_check(a) for a in v["args"]]) for v in variants]
    return _dispatch(compiled, _LazyJit(module, name))


def active() -> bool:
    """Whether the ahead-of-time compiled kernels are in use in this process."""
    return _table()[1] is not None


def _collect_signatures() -> dict[str, dict[str, Any]]:
    """Solve the scenes whose kernels a run calls (a cap, a design with its lower state off the
    path, the harmonic check) and return the dispatchers of :data:`snapjump_kernels.calls.KERNELS`
    that were called, per kernel module (each with the signatures it was called with)."""
    from numba.core.registry import CPUDispatcher

    from snapjump_cli.geometry import CapScene, Design
    from snapjump_cli.harmonics import check_harmonics
    from snapjump_cli.settings import MeshSettings, SolverSettings
    from snapjump_cli.solve import solve_checked, solve_scene

    solve_scene(CapScene(theta_deg=60.0, eta=30.0, bc="clamped"), MeshSettings(), SolverSettings())
    solve_scene(CapScene(theta_deg=60.0, eta=30.0, bc="clamped"), MeshSettings(order=1), SolverSettings())
    off_path = Design(eta_i=5.6, theta_i_deg=80.0, eta_o=15.0, theta_o_deg=82.0, mu_ratio=5.8)  # grid-1543
    res = solve_checked(off_path, MeshSettings(order=2, nt=2, aspect=3.0), SolverSettings())
    check_harmonics(res, 1)
    from snapjump_kernels.calls import KERNELS

    found: dict[str, dict[str, Any]] = {}
    for modname, names in KERNELS.items():
        mod = importlib.import_module(f"{__package__}.{modname}")
        for name in names:
            obj = getattr(mod, name)
            if isinstance(obj, CPUDispatcher) and obj.nopython_signatures:
                found.setdefault(modname, {})[name] = obj
    return found


def build() -> Path:
    """Compile the extension (see the module docstring) next to the kernels; returns its path.

    The new file replaces the old one by a rename, so processes that have the old one loaded
    keep a valid mapping."""
    import tempfile
    import warnings

    found = _collect_signatures()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numba.pycc's pending deprecation
        from numba.pycc import CC

    cc = CC(MODULE)
    cc.target_cpu = "host"  # the JIT's target: the same machine code
    exports: dict[str, dict[str, list]] = {}
    for modname, funcs in found.items():
        for name, disp in funcs.items():
            for k, sig in enumerate(disp.nopython_signatures):
                specs = [_arg_spec(t) for t in sig.args]
                if any(sp is None for sp in specs):
                    continue
                params = ", ".join(f"a{i}" for i in range(len(sig.args)))
                scope: dict[str, Any] = {"kernel": disp}
                exec(f"def wrapper({params}):\n    return kernel({params})\n", scope)  # noqa: S102
                export = f"{modname}__{name}__{k}"
                cc.export(export, sig)(scope["wrapper"])
                exports.setdefault(modname, {}).setdefault(name, []).append({"export": export, "args": specs})
    STAMP.unlink(missing_ok=True)  # no stale pairing while the extension is rewritten
    with tempfile.TemporaryDirectory(dir=HERE) as tmp:
        cc.output_dir = tmp
        cc.compile()
        built = next(Path(tmp).glob(f"{MODULE}*"))
        target = HERE / built.name
        os.replace(built, target)
    EXPORTS.write_text(json.dumps({"cpu": cpu_signature(), "kernels": exports}, indent=1) + "\n")
    STAMP.write_text(source_hash() + "\n")
    return target


def main(argv: list[str] | None = None) -> int:
    """``python -m snapjump_kernels.aot``: build the extension; exit 0 also when it cannot be built
    (the JIT remains), with the reason on stderr."""
    import time

    t0 = time.perf_counter()
    try:
        so = build()
    except Exception as exc:  # noqa: BLE001 - any failure leaves the JIT in place
        sys.stderr.write(f"snapjump_kernels.aot: not built ({type(exc).__name__}: {exc}); the kernels run JIT-compiled\n")
        return 0
    sys.stderr.write(f"snapjump_kernels.aot: built {so.name} in {time.perf_counter() - t0:.0f} s\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
