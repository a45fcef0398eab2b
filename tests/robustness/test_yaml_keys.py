"""A key given twice in a YAML input is an error naming the key and both lines (exit 2), in sweep
configs and optimize specs; so are a non-regular file that never ends and a file over the size
limit."""
from __future__ import annotations

import pytest

from conftest import run_cli
from snapjump_cli.sweep.checks import ConfigError, read_yaml

GRID = """grid:
  eta_i: [5]
  theta_i: [80]
  eta_o: [5]
  theta_o: [82]
  mu_ratio: [1]
"""

CASES = [
    ("sweep", GRID + "mesh: {order: 1}\nmesh: {order: 2}\n", "mesh", 7, 8),
    ("sweep", GRID.replace("  theta_o: [82]\n", "  theta_o: [82]\n  eta_i: [6]\n"), "grid.eta_i", 2, 6),
    ("sweep", "points:\n  - {eta_i: 6.2, theta_i: 80, eta_o: 12.1,\n     theta_o: 82, mu_ratio: 5.8, mu_ratio: 1}\n",
     "points[0].mu_ratio", 3, 3),
    ("optimize", "bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\nbudget: 10\n"
                 "seed: 1\nbudget: 20\n", "budget", 2, 4),
]


@pytest.mark.parametrize("command, text, key, first, second", CASES)
def test_duplicate_keys_are_refused_naming_both_lines(tmp_path, capsys, command, text, key, first, second):
    p = tmp_path / "in.yaml"
    p.write_text(text)
    code, _, err = run_cli(capsys, command, str(p), "-o", str(tmp_path / "r.parquet"))
    assert code == 2, err
    assert err.strip() == f"Error: {p}: {key}: duplicate key (lines {first} and {second}); give it once"
    assert list(tmp_path.iterdir()) == [p]


def test_the_first_duplicate_in_the_file_is_named_and_merge_keys_still_work(tmp_path):
    p = tmp_path / "in.yaml"
    p.write_text("a: 1\nb: {x: 1, x: 2}\na: 3\n")
    with pytest.raises(ConfigError, match=r"b.x: duplicate key \(lines 2 and 2\)"):
        read_yaml(p)
    p.write_text("base: &b {order: 2, nt: 2}\nmesh:\n  <<: *b\n  nt: 3\n")
    assert read_yaml(p)["mesh"] == {"order": 2, "nt": 3}


def test_a_file_that_never_ends_is_refused_or_read_only_up_to_the_limit(tmp_path):
    with pytest.raises(ConfigError, match="expected a regular file, got a character device"):
        read_yaml("/dev/zero")  # a device: refused before it is opened (issue 38)
    big = tmp_path / "big.yaml"
    big.write_bytes(b"#" * (2 << 20))
    with pytest.raises(ConfigError, match="larger than 1 MB"):
        read_yaml(big)  # a regular file: bounded by the size limit, not by memory
