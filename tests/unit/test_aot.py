"""The ahead-of-time compiled kernels (``snapjump_kernels.aot``): used only when built from the
current sources, called only with exactly the compiled argument types, and bit-identical to the
JIT-compiled kernels."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from snapjump_kernels import aot


@pytest.fixture(autouse=True)
def _fresh_table():
    """``aot._table`` is read once per process: each test reads it afresh, and leaves it so."""
    aot._table.cache_clear()
    yield
    aot._table.cache_clear()


def test_argument_checks_are_exact():
    ok = aot._arg_check(["array", "float64", 2, "C", True])
    a = np.zeros((3, 4))
    assert ok(a)
    assert not ok(np.asfortranarray(a)) and not ok(a[:, ::2]) and not ok(a.astype(np.float32)) and not ok(a[0])
    ro = a.copy()
    ro.flags.writeable = False
    assert not ok(ro) and not ok(a.tolist())
    assert aot._arg_check(["int"])(3) and not aot._arg_check(["int"])(True) and not aot._arg_check(["int"])(3.0)
    assert aot._arg_check(["float"])(3.0) and not aot._arg_check(["float"])(3)
    assert aot._arg_check(["bool"])(np.bool_(True)) and not aot._arg_check(["bool"])(1)


def test_a_mismatch_goes_to_the_dispatcher():
    calls = []

    def compiled(x):
        calls.append("compiled")
        return 1

    def jit(x):
        calls.append("jit")
        return 2

    f = aot._dispatch([(compiled, [aot._arg_check(["array", "float64", 1, "C", True])])], jit)
    assert f(np.zeros(3)) == 1 and f(np.zeros(6)[::2]) == 2 and f(np.zeros(3, dtype=np.int64)) == 2
    assert calls == ["compiled", "jit", "jit"] and f.jit is jit


def test_not_used_when_built_from_other_sources(tmp_path, monkeypatch):
    stamp = tmp_path / "stamp"
    stamp.write_text("0" * 64 + "\n")
    monkeypatch.setattr(aot, "STAMP", stamp)
    assert aot._table() == ({}, None)
    monkeypatch.setattr(aot, "STAMP", tmp_path / "missing")
    assert aot._table() == ({}, None)


def test_not_used_on_another_cpu(monkeypatch):
    if not aot.STAMP.is_file():
        pytest.skip("the ahead-of-time kernels are not built")
    assert aot._table()[1] is not None
    monkeypatch.setattr(aot, "cpu_signature", lambda: "another cpu")
    aot._table.cache_clear()
    assert aot._table() == ({}, None)


def test_not_used_when_switched_off(monkeypatch):
    monkeypatch.setenv("SNAPJUMP_NO_AOT", "1")
    assert aot._table() == ({}, None)


BUILT = pytest.mark.skipif(not aot.STAMP.is_file(), reason="the ahead-of-time kernels are not built (make install builds them)")


@BUILT
def test_a_curve_process_runs_without_numba():
    """With the extension built, solving the thin clamped cap never imports numba (the compiled
    kernels' LAPACK, behind ``np.linalg.inv``, comes from ``scipy.linalg.cython_lapack``)."""
    code = ("import sys\n"
            "from snapjump_cli.geometry import CapScene\n"
            "from snapjump_cli.settings import MeshSettings, SolverSettings\n"
            "from snapjump_cli.solve import solve_scene\n"
            "from snapjump_kernels import calls\n"
            "m = solve_scene(CapScene(theta_deg=60.0, eta=30.0, bc='clamped'), MeshSettings(), SolverSettings()).metrics\n"
            "assert m['snaps'] and calls.AOT\n"
            "print(sorted(k for k in sys.modules if k.split('.')[0] == 'numba'))\n")
    env = dict(os.environ, SNAPJUMP_NO_AOT="0")
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]", r.stdout


@BUILT
def test_built_kernels_are_in_use_and_bit_identical(tmp_path):
    """A built extension that matches the sources is in use, and the curve command's answers
    are the same bits with it and with the JIT (the thin clamped cap and design C)."""
    from snapjump_kernels import calls

    assert calls.AOT, "kernels/_aot.sha256 exists but the extension is not in use"
    assert hasattr(calls.bordered_factor, "jit")  # the compiled variants, with the dispatcher behind
    outs = {}
    for mode in ("aot", "jit"):
        env = dict(os.environ, SNAPJUMP_NO_AOT="1" if mode == "jit" else "0")
        for name, args in (("cap", ["--cap", "--theta", "60", "--eta", "30", "--bc", "clamped"]), ("C", ["--design", "C"])):
            out = tmp_path / f"{name}-{mode}.json"
            code = ("import sys; from snapjump_cli.cli import main; sys.exit(main(sys.argv[1:]))")
            r = subprocess.run([sys.executable, "-c", code, "curve", *args, "--format", "json"], env=env,
                               capture_output=True, text=True, timeout=300)
            assert r.returncode == 0, r.stderr
            out.write_text(r.stdout)
            outs[(name, mode)] = json.loads(r.stdout)
    for name in ("cap", "C"):
        a, b = outs[(name, "aot")], outs[(name, "jit")]
        ma, mb = a.get("metrics", a), b.get("metrics", b)
        keys = [k for k, v in ma.items() if isinstance(v, float) and not k.endswith("_s")]
        assert len(keys) > 10
        assert {k: ma[k] for k in keys} == {k: mb[k] for k in keys}, name
