"""bench/: the tools no make target runs answer ``--help`` (and the profiles find the library
functions they call), so a move in the library cannot leave them broken unnoticed."""
from __future__ import annotations

import importlib
import pkgutil

import pytest

import bench.profile

#: every module of bench/profile/, plus the bench tools that no make target runs
TOOLS = ["bench.grid_compare", "bench.followed_fig4"] + [
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


def test_follow_profile_finds_the_library() -> None:
    from bench.profile import follow

    fns = follow.api()
    assert set(fns) == set(follow._WHERE)
    assert all(callable(f) for f in fns.values())
