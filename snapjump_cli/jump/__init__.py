"""The two-mass spring-dashpot jump model (paper Fig. 4B, S5 eqs 15-25; docs/physics.md section 6)
and the ranking of a sweep by it. Import the model from here.

Modules: :mod:`.params` (``JumpParams``, ``JumpResult``, the input checks), :mod:`.closed_form`
(eqs 16-17, both phase kinds in closed form, the energy and lift-off bounds), :mod:`.events`
(impacts, lift-offs and apexes located on the closed form), :mod:`.batch` (one simulation or
many together), :mod:`.trajectory` (the conventions, ``jump_trajectory``, ``jump_height``),
:mod:`.ode` (the ``solve_ivp`` cross-check) and :mod:`.rank` (the jump model on every row of a
result table).
"""
from __future__ import annotations

from snapjump_cli.jump.closed_form import eigensystem, spring_stiffness, system_matrices
from snapjump_cli.jump.ode import jump_height_ode
from snapjump_cli.jump.params import JumpParams, JumpResult
from snapjump_cli.jump.trajectory import (
    JumpTrajectory,
    jump_height,
    jump_heights,
    jump_trajectory,
    masses,
)

__all__ = ["JumpParams", "JumpResult", "JumpTrajectory", "masses", "spring_stiffness", "eigensystem",
           "system_matrices", "jump_height", "jump_heights", "jump_trajectory", "jump_height_ode"]
