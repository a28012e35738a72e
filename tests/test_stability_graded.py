"""Graded mesh (paper Sec. 2.3): a settling disk on a uniform mesh against a graded one.

:mod:`fluidem.cases.graded`: the settling disk of ``fluidem bench settling-disk`` run to t* = 0.8
(dt = 0.02, 40 steps); the settling speed there against the graded run with h = 0.0125 at the
disk (growth 1.1 up to 4 h, 92686 DOFs; growth 1.2 up to 8 h is 3.4e-5 from it): U_REF below,
``benchmarks/results/stability_graded.md`` for the whole table.  A graded mesh with the uniform
mesh's size at the disk gives the same speed, or a closer one, with 3.7–13.5 times fewer DOFs.
Meshes much coarser than the 64-gon's edge re-triangulate at every step unless the smallest-angle
trigger has a margin (``MeshParams.min_angle_margin``, 0 by default).
"""

import pytest

from fluidem.cases.graded import graded_settling_scene, sedimentation_run, size_near_body
from fluidem.simulation import Simulation

#: u(t*) at t* = 0.8, dt = 0.02 on the graded mesh h = 0.0125, growth 1.1, h_max = 4 h (benchmark table)
U_REF = 0.05552383
GRADING = (1.2, 8.0)  # growth 1.2 away from the disk, up to 8 h


def test_grading_keeps_the_size_at_the_disk_and_drops_most_dofs():
    """h = 0.025 at the disk: the mean edge within one radius of the outline is 0.0268 (uniform)
    and 0.0248 (graded), 7.5 % apart; the graded mesh has 13.5x fewer DOFs (173400 / 12798)."""
    uniform = Simulation(graded_settling_scene(0.025, None))
    graded = Simulation(graded_settling_scene(0.025, GRADING))
    assert abs(size_near_body(graded) / size_near_body(uniform) - 1.0) < 0.2
    assert uniform.flow.dofs / graded.flow.dofs > 10.0


def test_graded_mesh_gives_the_settling_speed_at_t_star():
    """Growth 1.2 up to 8 h, h = 0.025 at the disk (12798 DOFs, about 4 s): u(t*) within
    2.9e-4 of the reference (the uniform h = 0.025 mesh, 173400 DOFs: 3.4e-4)."""
    r = sedimentation_run(0.025, GRADING, t_star=0.8, dt=0.02)
    assert r["steps"] == 40
    assert abs(r["u_star"] / U_REF - 1.0) < 6e-4


@pytest.mark.slow(seconds=50)
def test_graded_mesh_matches_the_uniform_mesh_of_the_same_size_at_the_disk():
    """h = 0.025: graded (growth 1.2) and uniform differ by 5.9e-5 in u(t*), both within 3.5e-4 of
    the reference; 13.5x fewer DOFs graded (about a minute, the uniform run)."""
    uniform = sedimentation_run(0.025, None, t_star=0.8, dt=0.02)
    graded = sedimentation_run(0.025, GRADING, t_star=0.8, dt=0.02)
    assert abs(graded["u_star"] / uniform["u_star"] - 1.0) < 1.5e-4
    assert uniform["dofs"] / graded["dofs"] > 10.0


@pytest.mark.slow(seconds=50)
def test_on_coarse_meshes_the_graded_one_is_the_closer():
    """h = 0.05 (both re-triangulate at every step): uniform −1.38e-2, graded (growth 1.2) −1.10e-2
    from the reference, with 7.7x fewer DOFs (43456 / 5650; about 80 s)."""
    uniform = sedimentation_run(0.05, None, t_star=0.8, dt=0.02)
    graded = sedimentation_run(0.05, GRADING, t_star=0.8, dt=0.02)
    e_u, e_g = uniform["u_star"] / U_REF - 1.0, graded["u_star"] / U_REF - 1.0
    assert e_u < e_g < 0.0
    assert abs(e_u - e_g) > 1e-3  # measured 2.8e-3
    assert uniform["dofs"] / graded["dofs"] > 5.0


def test_coarse_mesh_retriangulates_every_step_without_a_smallest_angle_margin():
    """h = 0.05 at the disk, 5 times the 64-gon's edge, graded (growth 1.2): the first mesh has
    elements below 15° next to the outline and, with no margin on the smallest-angle trigger (the
    default), re-triangulates at every step (41 triangulations in 40 steps; error −1.10e-2).  A 3°
    margin leaves 2 triangulations and an error of −8.1e-3 (about 7 s both)."""
    default = sedimentation_run(0.05, GRADING, t_star=0.8, dt=0.02)
    margin = sedimentation_run(0.05, GRADING, t_star=0.8, dt=0.02, min_angle_margin=3.0)
    assert default["triangulations"] == default["steps"] + 1
    assert margin["triangulations"] <= 3
    e_default, e_margin = default["u_star"] / U_REF - 1.0, margin["u_star"] / U_REF - 1.0
    assert e_default < e_margin < 0.0
    assert e_margin - e_default > 1e-3  # measured 2.9e-3
