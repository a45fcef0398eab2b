"""Regression of the answers: a few rows of the committed baseline (bench/regression/baseline.json,
recorded by the code before the speed work) solved again as the sweep solves them. Every row keeps
its status and flags, and dE, dy_pole and h_imp stay within 0.5 % (the whole sample, 257 rows, is
compared by ``make bench``)."""
from __future__ import annotations

import json

import pytest

from bench.regression import BASELINE, compare_rows, same_rows, scenes, solve_one

#: fast path rows (two of them self-crossing) and an invalid design
IDS = ("grid-0815", "grid-0169", "grid-1601", "grid-3364", "grid-3426", "grid-0321")


@pytest.fixture(scope="module")
def baseline():
    doc = json.loads(BASELINE.read_text())
    return doc, {r["id"]: r for r in doc["rows"]}


@pytest.mark.parametrize("rid", IDS)
def test_row_keeps_its_answer(baseline, rid):
    doc, rows = baseline
    item = next(s for s in scenes(doc["n_grid"], doc["seed"]) if s["id"] == rid)
    new = solve_one(item)
    assert compare_rows(rows[rid], new, 0.005) == []


def test_compare_rows_detects_a_changed_answer(baseline):
    _, rows = baseline
    b = rows["grid-0815"]
    assert compare_rows(b, dict(b), 0.005) == []
    assert compare_rows(b, {**b, "dE_J": b["dE_J"] * 1.006}, 0.005)
    assert compare_rows(b, {**b, "self_crossing": not b["self_crossing"]}, 0.005)
    assert compare_rows(b, {**b, "status": "failed"}, 0.005)


def test_the_bench_report_names_the_machine(tmp_path):
    """The CPU line of the throughput report: the model name and, from /proc/cpuinfo (here a
    fixture), family and model numbers, the clock and the widest vector extension (two machines
    of one name differ)."""
    from bench import runner
    from bench.regression import cpu_text

    text = ("processor\t: 0\nvendor_id\t: GenuineIntel\ncpu family\t: 6\nmodel\t\t: 167\n"
            "model name\t: Intel(R) Xeon(R) Processor\ncpu MHz\t\t: 2599.998\nflags\t\t: fpu sse4_2 avx avx2 avx512f\n\n"
            "processor\t: 1\nmodel name\t: another\n")
    fake = tmp_path / "cpuinfo"
    fake.write_text(text)
    info = runner.cpu_info(str(fake))
    assert info["cpu_model"] == "Intel(R) Xeon(R) Processor"
    assert info["cpu_id"] == "family 6 model 167, 2600 MHz, avx512f"
    assert cpu_text(str(fake)) == "Intel(R) Xeon(R) Processor; family 6 model 167, 2600 MHz, avx512f"
    amd = tmp_path / "amd"
    amd.write_text("processor\t: 0\nmodel name\t: AMD EPYC\ncpu family\t: 23\nmodel\t\t: 49\ncpu MHz\t\t: 2994.4\n"
                   "flags\t\t: fpu avx avx2\n")
    assert cpu_text(str(amd)) == "AMD EPYC; family 23 model 49, 2994 MHz, avx2"
    assert "cpu_id" not in runner.cpu_info(str(tmp_path / "none"))  # no /proc/cpuinfo: no invented line


def test_same_rows_sees_every_changed_value_but_timings(baseline):
    _, rows = baseline
    old = [rows["grid-0815"], rows["grid-0321"]]
    assert same_rows(old, [dict(r) for r in old]) == []
    assert same_rows(old, [{**old[0], "wall_s": 99.0}, old[1]]) == []
    changed = {**old[0], "dE_J": old[0]["dE_J"] * (1 + 2**-52)}  # one ulp
    assert same_rows(old, [changed, old[1]]) == [f"grid-0815 dE_J: {old[0]['dE_J']!r} -> {changed['dE_J']!r}"]
    assert same_rows(old, old[:1]) == ["grid-0321: only in the old rows"]
