"""Ahead-of-time compiled kernels: start-up without numba's run-time initialisation.

A process that calls a cached ``@njit`` kernel first pays for numba's own target (its lowering
registries, ~0.4 s, which also import ``scipy.linalg`` for a BLAS check) and for rebuilding each
kernel from the cache (~20 ms each). :func:`build` compiles the kernels the solver calls
(:data:`snapjump_kernels.calls.KERNELS`) into one extension module, ``snapjump_kernels/_aot*.so``,
with ``numba.pycc`` for this machine's CPU and with the signatures the solver actually uses
(collected by solving a few scenes first: :mod:`snapjump_cli.fe.precompile`, which ``make
install`` runs; this module never imports the solver). :mod:`snapjump_kernels.calls`,
the module the solver imports its kernels from, then hands out the compiled functions, and a
``snapjump curve`` process neither imports numba nor initialises its target.

Each exported function is a thin wrapper that calls the ``@njit`` kernel, so the kernel keeps its
own options (``error_model``, ``fastmath``) and the machine code is that of the JIT: the answers
are bit-identical (``tests/unit/test_aot.py``). A call whose argument types differ from the
compiled signatures (checked exactly: dtype, dimensions, contiguity, writability) goes to the
dispatcher, imported on first use.

The build's stamp (``_aot_build.json`` beside the kernels) records what it was built for: the
kernel sources' hash, this CPU (model and feature flags), the exported signatures, or why the
build failed. The extension is used only when the stamp matches the current sources and this
CPU and ``SNAPJUMP_NO_AOT`` is not set (:func:`build_status` says why not otherwise); everything
then runs through the JIT as before. ``make install`` checks the stamp each time
(:func:`stale_reason`, no numba) and rebuilds when the sources or the CPU differ; a failed build
is stamped too (:func:`record_failure`) and not retried until they do. The kernel
modules themselves are never modified: a kernel calling another still calls its dispatcher.
"""
from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib
import json
import os
from pathlib import Path
from typing import Any, Callable, Iterator

from snapjump_kernels import source_hash

HERE = Path(__file__).resolve().parent
MODULE = "_aot"
#: what the extension was built for (not a .py: it would change the sources' hash)
STAMP_NAME = "_aot_build.json"
CPUINFO = "/proc/cpuinfo"


def arg_spec(t: Any) -> list | None:
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


def arg_check(spec: list) -> Callable[[Any], bool]:
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


def signature_check(specs: list[list]) -> Callable[[tuple], bool]:
    """Whether a tuple of Python arguments matches the signature ``specs`` (one :func:`arg_spec` per
    argument) exactly: the same test as :func:`arg_check` on every argument, written out as one
    generated function (no call and no generator per argument: the checks of a 39-argument kernel
    cost ~4 % of a sweep's CPU as separate closures)."""
    import numpy as np

    scope: dict[str, Any] = {"_nd": np.ndarray, "_ints": (int, np.integer), "_bools": (bool, np.bool_),
                             "_floats": (float, np.floating)}
    n = len(specs)
    body = [f"    if len(args) != {n}:", "        return False"]
    if n:
        body.append("    " + ", ".join(f"a{i}" for i in range(n)) + (", = args" if n == 1 else " = args"))
    for i, spec in enumerate(specs):
        a = f"a{i}"
        kind = spec[0]
        if kind == "array":
            scope[f"_dt{i}"] = np.dtype(spec[1])
            nd, layout, mutable = spec[2], spec[3], spec[4]
            body.append(f"    if type({a}) is not _nd or not ({a}.dtype is _dt{i} or {a}.dtype == _dt{i}) "
                        f"or {a}.ndim != {int(nd)}:")
            body.append("        return False")
            flags = []
            if layout == "C":
                flags.append("f.c_contiguous")
            elif layout == "F":
                flags.append("f.f_contiguous")
            if mutable:
                flags.append("f.writeable")
            if flags:
                body.append(f"    f = {a}.flags")
                body.append(f"    if not ({' and '.join(flags)}):")
                body.append("        return False")
        elif kind == "bool":
            body.append(f"    if not (type({a}) is bool or isinstance({a}, _bools)):")
            body.append("        return False")
        elif kind == "int":
            body.append(f"    if not (type({a}) is int or (isinstance({a}, _ints) and not isinstance({a}, _bools))):")
            body.append("        return False")
        else:
            body.append(f"    if not (type({a}) is float or isinstance({a}, _floats)):")
            body.append("        return False")
    body.append("    return True")
    exec("def check(args):\n" + "\n".join(body) + "\n", scope)  # noqa: S102
    return scope["check"]


def dispatch(variants: list[tuple[Callable, Any]], jit: Any) -> Callable:
    """The kernel as callers see it: the first compiled variant whose argument types match
    exactly, else the JIT dispatcher. A variant's checks are a list of per-argument checks
    (:func:`arg_check`) or one check of the whole argument tuple (:func:`signature_check`)."""

    def whole(checks):
        if callable(checks):
            return checks
        return lambda args: len(args) == len(checks) and all(c(a) for c, a in zip(checks, args))

    table = [(whole(checks), compiled) for compiled, checks in variants]

    def call(*args):
        for check, compiled in table:
            if check(args):
                return compiled(*args)
        return jit(*args)

    call.__name__ = getattr(jit, "__name__", "kernel")
    call.__doc__ = getattr(jit, "__doc__", None)
    call.jit = jit  # what a mismatch calls (the dispatcher, imported on first use)
    return call


def cpu_fields(cpuinfo: str | Path = CPUINFO) -> dict[str, str]:
    """The first processor's entries of ``cpuinfo`` (``/proc/cpuinfo``; empty where there is none)."""
    fields: dict[str, str] = {}
    try:
        with open(cpuinfo) as fh:
            for line in fh:
                if not line.strip():
                    break  # the first processor is enough
                key, _, value = line.partition(":")
                fields[key.strip()] = value.strip()
    except OSError:
        pass
    return fields


def cpu_signature(cpuinfo: str | Path = CPUINFO) -> str:
    """What identifies this CPU for the compiled code (built for the host CPU, it may use
    instructions another CPU lacks): the model name and feature flags of ``cpuinfo``, else
    ``platform.processor()``, with ``platform.machine()``."""
    import platform

    fields = cpu_fields(cpuinfo)
    text = "|".join([fields.get("model name", platform.processor()), fields.get("flags", ""), platform.machine()])
    return hashlib.sha256(text.encode()).hexdigest()[:16]


#: The environment settings with which numba's JIT makes other machine code on the same CPU
#: (its target CPU and features, AVX, optimisation and vectorisation); numba's defaults where unset.
NUMBA_CODEGEN_ENV = ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES", "NUMBA_ENABLE_AVX", "NUMBA_OPT",
                     "NUMBA_LOOP_VECTORIZE", "NUMBA_SLP_VECTORIZE")


def numba_codegen_env() -> dict[str, str]:
    """Those of :data:`NUMBA_CODEGEN_ENV` that are set in this process (a build made under other
    ones is not the JIT's code here: ``NUMBA_ENABLE_AVX=0`` moved the cap's answers by round-off)."""
    return {k: os.environ[k] for k in NUMBA_CODEGEN_ENV if k in os.environ}


def read_stamp(folder: Path = HERE) -> dict | None:
    """The build's stamp in ``folder`` (None when there is none or it cannot be read)."""
    try:
        stamp = json.loads((folder / STAMP_NAME).read_text())
    except (OSError, ValueError):
        return None
    return stamp if isinstance(stamp, dict) else None


def stale_reason(stamp: dict | None, cpuinfo: str | Path = CPUINFO) -> str:
    """Why a build with this ``stamp`` does not fit these kernel sources on this CPU ('' if it
    does, whether it was built or its build failed): what ``make install`` checks before
    building again. Imports no numba."""
    if stamp is None:
        return "not built"
    if stamp.get("sources") != source_hash():
        return "built from other kernel sources"
    if stamp.get("cpu") != cpu_signature(cpuinfo):
        return f"built for another CPU ({stamp.get('cpu_model', '?')})"
    if stamp.get("numba_env", {}) != numba_codegen_env():
        return f"built under other numba code-generation settings ({stamp.get('numba_env', {})})"
    return ""


def build_status(folder: Path = HERE, cpuinfo: str | Path = CPUINFO) -> str:
    """Why the build in ``folder`` is not used in this process ('' when it is): switched off by
    ``SNAPJUMP_NO_AOT``, not built, built from other sources or for another CPU, or failed."""
    if os.environ.get("SNAPJUMP_NO_AOT", "") not in ("", "0"):
        return "switched off (SNAPJUMP_NO_AOT is set)"
    stamp = read_stamp(folder)
    why = stale_reason(stamp, cpuinfo)
    if why:
        return why
    if not stamp.get("built"):
        return f"its build failed ({stamp.get('reason', '?')})"
    if not any(folder.glob(f"{MODULE}*.so")):
        return f"built, but its extension file ({MODULE}*.so) is missing"
    return ""


def _import_extension(folder: Path) -> Any:
    """The compiled extension module of ``folder`` (this package's, imported as a submodule)."""
    if folder.resolve() != HERE:
        raise ImportError(f"no importable extension module in {folder}")
    return importlib.import_module(f"{__package__}.{MODULE}")


def load_build(folder: Path = HERE, cpuinfo: str | Path = CPUINFO,
               load: Callable[[Path], Any] = _import_extension) -> tuple[dict[str, dict[str, list]], Any]:
    """The export table and the extension of the build in ``folder``, if it is usable here
    (:func:`build_status`), else ``({}, None)``; ``load`` imports the extension module. Imports
    no numba."""
    if build_status(folder, cpuinfo):
        return {}, None
    try:
        exports = read_stamp(folder)["kernels"]
        ext = load(folder)
    except (OSError, ImportError, KeyError, TypeError):
        return {}, None
    return exports, ext


@functools.lru_cache(maxsize=1)
def _table() -> tuple[dict[str, dict[str, list]], Any]:
    """:func:`load_build` of this package's folder, read once per process."""
    return load_build()


class _LazyJit:
    """The dispatcher of ``snapjump_kernels.<module>.<name>``, imported (with numba) on first use."""

    def __init__(self, module: str, name: str) -> None:
        self.module, self.name, self._f = module, name, None

    def __call__(self, *args):
        if self._f is None:
            self._f = getattr(importlib.import_module(f"{__package__}.{self.module}"), self.name)
        return self._f(*args)


def lazy_jit(module: str, name: str) -> Callable:
    """The JIT dispatcher of ``snapjump_kernels.<module>.<name>``, its module imported (with numba)
    when it is first called: a kernel that is never compiled ahead of time
    (:data:`snapjump_kernels.calls.JIT_KERNELS`)."""
    return _LazyJit(module, name)


def kernel(module: str, name: str, table: tuple[dict, Any] | None = None) -> Callable:
    """``snapjump_kernels.<module>.<name>`` as the solver calls it: the compiled variants first
    (exact argument match), the JIT dispatcher otherwise; the plain dispatcher when there is no
    usable extension (:mod:`snapjump_kernels.calls` builds its names with this). ``table``: a
    :func:`load_build` result (this package's build by default)."""
    exports, ext = _table() if table is None else table
    if ext is None:
        return getattr(importlib.import_module(f"{__package__}.{module}"), name)
    variants = exports.get(module, {}).get(name)
    if not variants:  # not compiled ahead of time: the dispatcher, but only when first called
        return _LazyJit(module, name)
    compiled = [(getattr(ext, v["export"]), signature_check(v["args"])) for v in variants]
    return dispatch(compiled, _LazyJit(module, name))


def active() -> bool:
    """Whether the ahead-of-time compiled kernels are in use in this process."""
    return _table()[1] is not None


def _what_for(cpuinfo: str | Path = CPUINFO) -> dict[str, str]:
    """The stamp's record of what a build is for: the kernel sources, this CPU and numba's
    code-generation settings."""
    return {"sources": source_hash(), "cpu": cpu_signature(cpuinfo),
            "cpu_model": cpu_fields(cpuinfo).get("model name", "?"), "numba_env": numba_codegen_env()}


def _write_stamp(stamp: dict, folder: Path = HERE) -> None:
    tmp = folder / (STAMP_NAME + ".tmp")
    tmp.write_text(json.dumps(stamp, indent=1) + "\n")
    os.replace(tmp, folder / STAMP_NAME)


@contextlib.contextmanager
def jit_target() -> Iterator[None]:
    """Inside the block, numba's ahead-of-time code generator targets exactly what the JIT targets:
    the host CPU's name *and* the JIT's feature list (``numba.core.codegen.get_host_cpu_features``).

    ``numba.pycc`` with ``target_cpu = "host"`` takes the CPU's name only and lets LLVM infer the
    features from it. Where that differs from the features the JIT uses, the machine code differs:
    on a virtual machine that hides some of the model's extensions the build would use
    instructions the CPU lacks, and where numba turns AVX off (``NUMBA_ENABLE_AVX``; Sandy and Ivy
    Bridge by default) the vector width of :func:`snapjump_kernels.banded.dot_any_order`'s
    reassociated sum, hence its round-off, would differ from the JIT's."""
    from numba.core import codegen

    cls = codegen.AOTCPUCodegen
    if not hasattr(cls, "_customize_tm_features") or not hasattr(cls, "_get_host_cpu_features"):
        raise RuntimeError("numba's AOT code generator has changed: cannot give it the JIT's CPU features")
    original = cls.__dict__.get("_customize_tm_features")
    cls._customize_tm_features = lambda self: self._get_host_cpu_features()
    try:
        yield
    finally:
        if original is None:
            del cls._customize_tm_features
        else:
            cls._customize_tm_features = original


def build(found: dict[str, dict[str, Any]], cpuinfo: str | Path = CPUINFO) -> Path:
    """Compile the extension (see the module docstring) next to the kernels and write its stamp;
    returns its path. ``found``: kernel module -> name -> the ``@njit`` dispatcher, with the
    signatures it was compiled for (what a run calls: :func:`snapjump_cli.fe.precompile.collect_signatures`).

    The new file replaces the old one by a rename, so processes that have the old one loaded
    keep a valid mapping."""
    import tempfile
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numba.pycc's pending deprecation
        from numba.pycc import CC

    cc = CC(MODULE)
    cc.target_cpu = "host"  # the JIT's target (with its features: jit_target): the same machine code
    exports: dict[str, dict[str, list]] = {}
    for modname, funcs in found.items():
        for name, disp in funcs.items():
            for k, sig in enumerate(disp.nopython_signatures):
                specs = [arg_spec(t) for t in sig.args]
                if any(sp is None for sp in specs):
                    continue
                params = ", ".join(f"a{i}" for i in range(len(sig.args)))
                scope: dict[str, Any] = {"kernel": disp}
                exec(f"def wrapper({params}):\n    return kernel({params})\n", scope)  # noqa: S102
                export = f"{modname}__{name}__{k}"
                cc.export(export, sig)(scope["wrapper"])
                exports.setdefault(modname, {}).setdefault(name, []).append({"export": export, "args": specs})
    for old in (STAMP_NAME, "_aot.sha256", "_aot_exports.json"):  # (the last two: an older build's stamp)
        (HERE / old).unlink(missing_ok=True)  # no stale pairing while the extension is rewritten
    with tempfile.TemporaryDirectory(dir=HERE) as tmp, jit_target():
        cc.output_dir = tmp
        cc.compile()
        built = next(Path(tmp).glob(f"{MODULE}*"))
        target = HERE / built.name
        os.replace(built, target)
    _write_stamp({**_what_for(cpuinfo), "built": True, "kernels": exports})
    return target


def record_failure(reason: str, cpuinfo: str | Path = CPUINFO) -> None:
    """Stamp a failed build: these sources on this CPU are not tried again (:func:`stale_reason`)."""
    _write_stamp({**_what_for(cpuinfo), "built": False, "reason": reason[:500]})
