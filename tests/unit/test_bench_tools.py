"""bench/: the tools no make target runs answer ``--help`` (and the profiles find the library
functions they call), so a move in the library cannot leave them broken unnoticed."""
from __future__ import annotations

import importlib
import pkgutil

import pytest

import bench.profile

#: every module of bench/profile/, plus the bench tools that no make target runs
TOOLS = ["bench.grid_compare", "bench.followed_fig4", "bench.arbiter"] + [
    f"bench.profile.{m.name}" for m in pkgutil.iter_modules(bench.profile.__path__)]


@pytest.mark.parametrize("name", TOOLS)
def test_help(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    mod = importlib.import_module(name)
    with pytest.raises(SystemExit) as e:
        mod.main(["--help"])
    assert e.value.code == 0
    assert "usage:" in capsys.readouterr().out


def test_profiles_listed() -> None:
    assert "bench.profile.follow" in TOOLS


def test_follow_profile_stages_are_library_functions() -> None:
    """The stages ``--cprofile`` reports are found by function name: each must still exist."""
    from bench.profile import follow

    names = set()
    for m in pkgutil.walk_packages(importlib.import_module("snapjump_cli.fe").__path__, "snapjump_cli.fe."):
        mod = importlib.import_module(m.name)
        names |= {n for n, v in vars(mod).items() if callable(v)}
        names |= {n for c in vars(mod).values() if isinstance(c, type) for n in vars(c)}
    assert set(follow.STAGES) <= names, set(follow.STAGES) - names
