"""The ahead-of-time compiled kernels (``snapjump_kernels.aot``): used only when built from the
current sources on this CPU, called only with exactly the compiled argument types, and
bit-identical to the JIT-compiled kernels.

The guard is tested on fake builds in a temporary folder (a stamp and a stand-in extension) with
fixture CPUs, so these tests do not depend on this machine or on whether ``make install`` built
the real extension; the real extension is tested only where it is in use (``calls.AOT``)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import types

import numpy as np
import pytest

from snapjump_kernels import aot, calls, source_hash

XEON = ("processor\t: 0\nvendor_id\t: GenuineIntel\ncpu family\t: 6\nmodel\t\t: 167\n"
        "model name\t: Intel(R) Xeon(R) Processor\nflags\t\t: fpu sse4_2 avx avx2 avx512f\n\n"
        "processor\t: 1\nmodel name\t: Intel(R) Xeon(R) Processor\n")
EPYC = "processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel name\t: AMD EPYC\nflags\t\t: fpu sse4_2 avx avx2\n\n"

#: the one compiled variant of the fake build: ``sym_band_matvec(C float64 2-d, C float64 1-d)``
SPECS = [["array", "float64", 2, "C", True], ["array", "float64", 1, "C", True]]


@pytest.fixture
def cpus(tmp_path):
    """Two fixture CPUs (``/proc/cpuinfo`` texts): the one the fake build was made on, and another."""
    (tmp_path / "xeon").write_text(XEON)
    (tmp_path / "epyc").write_text(EPYC)
    return tmp_path / "xeon", tmp_path / "epyc"


@pytest.fixture
def fake_build(tmp_path, cpus, monkeypatch):
    """A build in a temporary folder, made for these kernel sources on the Xeon fixture: its stamp,
    and a loader that hands out a stand-in extension (whose one export says it was called)."""
    monkeypatch.setenv("SNAPJUMP_NO_AOT", "")  # unset for the guard; restored afterwards
    for k in aot.NUMBA_CODEGEN_ENV:  # numba's defaults, as the stamp below was made under
        monkeypatch.delenv(k, raising=False)
    folder = tmp_path / "build"
    folder.mkdir()
    stamp = {"sources": source_hash(), "cpu": aot.cpu_signature(cpus[0]), "cpu_model": "Intel(R) Xeon(R) Processor",
             "built": True, "kernels": {"banded": {"sym_band_matvec": [{"export": "banded__sym_band_matvec__0",
                                                                       "args": SPECS}]}}}
    (folder / aot.STAMP_NAME).write_text(json.dumps(stamp))
    (folder / "_aot.so").write_bytes(b"")  # the extension file (the loader below stands in for it)
    ext = types.SimpleNamespace(banded__sym_band_matvec__0=lambda *a: "compiled")
    loaded = []

    def load(where):
        loaded.append(where)
        return ext

    return types.SimpleNamespace(folder=folder, stamp=stamp, ext=ext, load=load, loaded=loaded)


def _restamp(fb, **changes):
    stamp = {**fb.stamp, **changes}
    (fb.folder / aot.STAMP_NAME).write_text(json.dumps(stamp))
    return stamp


def test_argument_checks_are_exact():
    ok = aot.arg_check(["array", "float64", 2, "C", True])
    a = np.zeros((3, 4))
    assert ok(a)
    assert not ok(np.asfortranarray(a)) and not ok(a[:, ::2]) and not ok(a.astype(np.float32)) and not ok(a[0])
    ro = a.copy()
    ro.flags.writeable = False
    assert not ok(ro) and not ok(a.tolist())
    assert aot.arg_check(["int"])(3) and not aot.arg_check(["int"])(True) and not aot.arg_check(["int"])(3.0)
    assert aot.arg_check(["float"])(3.0) and not aot.arg_check(["float"])(3)
    assert aot.arg_check(["bool"])(np.bool_(True)) and not aot.arg_check(["bool"])(1)


def test_the_signature_check_is_the_argument_checks():
    """One generated check of the whole argument tuple answers as the per-argument checks do."""
    specs = [["array", "float64", 2, "C", True], ["array", "float64", 1, "A", False], ["array", "int64", 1, "C", True],
             ["array", "float64", 2, "F", True], ["array", "bool", 1, "C", False], ["int"], ["float"], ["bool"]]
    a = np.zeros((3, 4))
    ro = a.copy()
    ro.flags.writeable = False
    values = [a, np.asfortranarray(a), a[:, ::2], a[0], a[:, 0], a.astype(np.float32), ro, ro[0], np.zeros(3, np.int64),
              np.zeros(3, np.int32), np.zeros(3, bool), a.tolist(), 3, np.int64(3), True, np.bool_(False), 3.0,
              np.float64(3.0), np.float32(3.0), None, "x"]
    for spec in specs:
        one, whole = aot.arg_check(spec), aot.signature_check([spec])
        for v in values:
            assert whole((v,)) == one(v), (spec, v)
        assert not whole(()) and not whole((values[0], values[0]))
    whole = aot.signature_check(specs[:3])
    assert whole((a, a[0], np.zeros(2, np.int64))) and not whole((a, a[0], np.zeros(2)))
    assert aot.signature_check([])(()) and not aot.signature_check([])((1,))


def test_a_mismatch_goes_to_the_dispatcher():
    calls_made = []

    def compiled(x):
        calls_made.append("compiled")
        return 1

    def jit(x):
        calls_made.append("jit")
        return 2

    f = aot.dispatch([(compiled, [aot.arg_check(["array", "float64", 1, "C", True])])], jit)
    assert f(np.zeros(3)) == 1 and f(np.zeros(6)[::2]) == 2 and f(np.zeros(3, dtype=np.int64)) == 2
    assert calls_made == ["compiled", "jit", "jit"] and f.jit is jit


def test_the_cpu_is_read_from_the_file_given(cpus):
    xeon, epyc = cpus
    assert aot.cpu_fields(xeon)["model name"] == "Intel(R) Xeon(R) Processor"
    assert aot.cpu_fields(xeon)["flags"].endswith("avx512f")  # the first processor only
    assert aot.cpu_signature(xeon) != aot.cpu_signature(epyc)
    assert aot.cpu_fields(xeon.parent / "missing") == {}


def test_a_matching_build_is_used(fake_build, cpus):
    table = aot.load_build(fake_build.folder, cpus[0], fake_build.load)
    assert table == (fake_build.stamp["kernels"], fake_build.ext) and fake_build.loaded == [fake_build.folder]
    assert aot.build_status(fake_build.folder, cpus[0]) == ""
    f = aot.kernel("banded", "sym_band_matvec", table)
    assert f(np.zeros((2, 3)), np.zeros(2)) == "compiled"
    assert isinstance(f.jit, aot._LazyJit) and f.jit._f is None  # the dispatcher is not imported for it
    lazy = aot.kernel("banded", "band_ldlt", table)  # not in the build: the dispatcher, on first call
    assert isinstance(lazy, aot._LazyJit) and lazy._f is None


def test_not_used_under_other_numba_code_generation_settings(fake_build, cpus, monkeypatch):
    """A build made with numba's defaults is not the JIT's code where the JIT makes other code on
    the same CPU (``NUMBA_ENABLE_AVX=0``, numba's own default on Sandy and Ivy Bridge), and the other
    way round: ``make install`` builds again."""
    assert aot.build_status(fake_build.folder, cpus[0]) == ""
    monkeypatch.setenv("NUMBA_ENABLE_AVX", "0")
    assert aot.load_build(fake_build.folder, cpus[0], fake_build.load) == ({}, None)
    assert aot.build_status(fake_build.folder, cpus[0]).startswith("built under other numba code-generation settings")
    assert aot._what_for(cpus[0])["numba_env"] == {"NUMBA_ENABLE_AVX": "0"}  # what a build here records
    _restamp(fake_build, numba_env={"NUMBA_ENABLE_AVX": "0"})
    assert aot.build_status(fake_build.folder, cpus[0]) == ""
    monkeypatch.delenv("NUMBA_ENABLE_AVX")
    assert aot.build_status(fake_build.folder, cpus[0]).startswith("built under other numba code-generation settings")


def test_not_used_on_another_cpu(fake_build, cpus):
    assert aot.load_build(fake_build.folder, cpus[1], fake_build.load) == ({}, None)
    assert fake_build.loaded == []
    assert aot.build_status(fake_build.folder, cpus[1]) == "built for another CPU (Intel(R) Xeon(R) Processor)"
    from snapjump_kernels import banded

    assert aot.kernel("banded", "sym_band_matvec", ({}, None)) is banded.sym_band_matvec  # the plain dispatcher


def test_not_used_when_built_from_other_sources(fake_build, cpus):
    _restamp(fake_build, sources="0" * 64)
    assert aot.load_build(fake_build.folder, cpus[0], fake_build.load) == ({}, None)
    assert aot.build_status(fake_build.folder, cpus[0]) == "built from other kernel sources"


def test_not_used_without_a_readable_stamp(fake_build, cpus):
    (fake_build.folder / aot.STAMP_NAME).write_text("{not json")
    assert aot.load_build(fake_build.folder, cpus[0], fake_build.load) == ({}, None)
    (fake_build.folder / aot.STAMP_NAME).unlink()
    assert aot.load_build(fake_build.folder, cpus[0], fake_build.load) == ({}, None)
    assert aot.build_status(fake_build.folder, cpus[0]) == "not built"
    assert fake_build.loaded == []


def test_not_used_when_its_build_failed(fake_build, cpus):
    stamp = _restamp(fake_build, built=False, reason="CompilerError: no C compiler", kernels=None)
    assert aot.load_build(fake_build.folder, cpus[0], fake_build.load) == ({}, None)
    assert aot.build_status(fake_build.folder, cpus[0]) == "its build failed (CompilerError: no C compiler)"
    assert aot.stale_reason(stamp, cpus[0]) == ""  # not retried until the sources or the CPU change


def test_not_used_when_the_extension_cannot_be_imported(fake_build, cpus):
    def broken(where):
        raise ImportError("built for another Python")

    assert aot.load_build(fake_build.folder, cpus[0], broken) == ({}, None)


def test_not_used_when_switched_off(fake_build, cpus, monkeypatch):
    monkeypatch.setenv("SNAPJUMP_NO_AOT", "1")
    assert aot.load_build(fake_build.folder, cpus[0], fake_build.load) == ({}, None)
    assert aot.build_status(fake_build.folder, cpus[0]) == "switched off (SNAPJUMP_NO_AOT is set)"
    monkeypatch.setenv("SNAPJUMP_NO_AOT", "0")
    assert aot.load_build(fake_build.folder, cpus[0], fake_build.load)[1] is fake_build.ext


def test_install_rebuilds_exactly_when_the_stamp_is_stale(fake_build, cpus, monkeypatch):
    """``make install`` runs ``precompile.main(["--if-stale"])`` every time: a build only when the
    stamp was made for other sources or another CPU (or there is none); a failed build is not
    retried, and its failure is stamped."""
    from snapjump_cli.fe import precompile

    xeon, epyc = cpus
    assert aot.stale_reason(fake_build.stamp, xeon) == ""
    assert aot.stale_reason(fake_build.stamp, epyc).startswith("built for another CPU")
    assert aot.stale_reason({**fake_build.stamp, "sources": "x"}, xeon) == "built from other kernel sources"
    assert aot.stale_reason(None, xeon) == "not built"

    builds, failures = [], []
    monkeypatch.setattr(precompile, "collect_signatures", lambda: {"found": "signatures"})
    monkeypatch.setattr(aot, "build", lambda found, cpuinfo: builds.append((found, cpuinfo)) or fake_build.folder / "_aot.so")
    monkeypatch.setattr(aot, "record_failure", lambda reason, cpuinfo: failures.append(reason))
    for stamp, cpu, expect in ((fake_build.stamp, xeon, 0), (fake_build.stamp, epyc, 1), (None, xeon, 1),
                               ({**fake_build.stamp, "sources": "x"}, xeon, 1),
                               ({**fake_build.stamp, "built": False, "reason": "no compiler"}, xeon, 0)):
        builds.clear()
        monkeypatch.setattr(aot, "read_stamp", lambda folder=aot.HERE, s=stamp: s)
        assert precompile.main(["--if-stale"], cpuinfo=cpu) == 0
        assert builds == [({"found": "signatures"}, cpu)] * expect, (stamp, cpu)
    assert failures == []

    def broken(found, cpuinfo):
        raise RuntimeError("no C compiler")

    monkeypatch.setattr(aot, "build", broken)
    assert precompile.main([], cpuinfo=xeon) == 0  # the JIT remains
    assert failures == ["RuntimeError: no C compiler"]


def test_the_build_here_is_used_exactly_when_its_stamp_matches():
    """In every state of this checkout (no build, one for another CPU or other sources,
    ``SNAPJUMP_NO_AOT`` set, a matching build) the kernels' choice follows the guard."""
    status = aot.build_status()
    assert calls.AOT == (aot.load_build()[1] is not None)
    if calls.AOT:
        assert status == ""
        assert hasattr(calls.bordered_factor, "jit")  # the compiled variants, with the dispatcher behind
    elif status:
        assert not hasattr(calls.bordered_factor, "jit")


ACTIVE = pytest.mark.skipif(not calls.AOT, reason=f"the ahead-of-time kernels are not in use here: {aot.build_status()}")


@ACTIVE
def test_a_curve_process_runs_without_numba():
    """With the extension in use, solving the thin clamped cap never imports numba (the compiled
    kernels' LAPACK, behind ``np.linalg.inv``, comes from ``scipy.linalg.cython_lapack``)."""
    code = ("import sys\n"
            "from snapjump_cli.geometry.caps import CapScene\n"
            "from snapjump_cli.settings import MeshSettings, SolverSettings\n"
            "from snapjump_cli.fe.solve import solve_scene\n"
            "from snapjump_kernels import calls\n"
            "m = solve_scene(CapScene(theta_deg=60.0, eta=30.0, bc='clamped'), MeshSettings(), SolverSettings()).metrics\n"
            "assert m['snaps'] and calls.AOT\n"
            "print(sorted(k for k in sys.modules if k.split('.')[0] == 'numba'))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]", r.stdout


@ACTIVE
def test_built_kernels_are_bit_identical():
    """The curve command's answers are the same bits with the extension and with the JIT (the
    thin clamped cap and design C)."""
    outs = {}
    for mode in ("aot", "jit"):
        env = dict(os.environ, SNAPJUMP_NO_AOT="1" if mode == "jit" else "0")
        for name, args in (("cap", ["--cap", "--theta", "60", "--eta", "30", "--bc", "clamped"]), ("C", ["--design", "C"])):
            code = "import sys; from snapjump_cli.cli import main; sys.exit(main(sys.argv[1:]))"
            r = subprocess.run([sys.executable, "-c", code, "curve", *args, "--format", "json"], env=env,
                               capture_output=True, text=True, timeout=300)
            assert r.returncode == 0, r.stderr
            outs[(name, mode)] = json.loads(r.stdout)
    for name in ("cap", "C"):
        a, b = outs[(name, "aot")], outs[(name, "jit")]
        ma, mb = a.get("metrics", a), b.get("metrics", b)
        keys = [k for k, v in ma.items() if isinstance(v, float) and not k.endswith("_s")]
        assert len(keys) > 10
        assert {k: ma[k] for k in keys} == {k: mb[k] for k in keys}, name


def test_the_build_targets_the_jits_cpu_features():
    """Inside ``jit_target`` numba's ahead-of-time code generator gets the CPU name and the feature
    list of the JIT (not only the name, from which LLVM would infer features the JIT may not use:
    a virtual CPU hiding extensions, or NUMBA_ENABLE_AVX=0), on any host; outside, numba's own."""
    from numba.core import codegen
    from numba.core.registry import cpu_target

    jit = cpu_target.target_context.codegen()
    with aot.jit_target():
        inside = codegen.AOTCPUCodegen("snapjump_test", cpu_name="host")
    assert inside._tm_features == jit._tm_features and inside._get_host_cpu_name() == jit._get_host_cpu_name()
    assert codegen.AOTCPUCodegen("snapjump_test", cpu_name="host")._tm_features == ""  # restored
