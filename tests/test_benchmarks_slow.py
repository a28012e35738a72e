"""Fine-level benchmark checks against the published values (slow: run in CI, skip locally
with ``-m "not slow"``).  Tolerances are the targets of the fluid-core specification where the
measured errors meet them, otherwise 2x the measured error (stated next to each).

The tests share nothing, so each may run on any worker with ``-n`` (conftest.py); ``seconds``
is each one's wall time with one BLAS thread on a 2-core machine, which orders them longest first.
"""

import pytest

from fluidem.cases.dfg import dfg_2d1


@pytest.mark.slow(seconds=19)
def test_dfg_2d1_p3_level_2():
    """P3/P2 at level 2 (107k DOFs; 19 s at a load average of 2, 140 s at 9): measured c_D
    3.2e-7, c_L 2.6e-6, Δp 2.9e-4 relative.  (The fixed-slope level-3 mesh, 120k DOFs, had
    c_D 8.8e-8, c_L 3.8e-7, Δp 1.5e-5: at equal DOFs it puts more cells at the cylinder;
    level 3 of the halving family, 442k DOFs, is too slow for this suite.)"""
    res = dfg_2d1("p3", 2)
    errs = res.relative_errors()
    assert errs["cd"] < 8e-7
    assert errs["cl"] < 6.5e-6
    assert errs["dp"] < 7.3e-4


# Relative errors (c_D, c_L, Δp) measured on the default (halving) meshes, and on the fixed-slope
# meshes used before, where P2/P1 and P2+bubble stalled:
#   th  level 2 (44.0k DOFs): 2.44e-6, 9.75e-4, 3.51e-3   fixed-slope level 2: 1.40e-5, 1.23e-3, 1.57e-3
#   th  level 3 (181k DOFs):  5.11e-7, 1.77e-4, 2.59e-4   fixed-slope level 3: 5.29e-6, 8.38e-4, 4.78e-4
#   p2b level 1 (21.8k DOFs): 2.43e-4, 4.82e-2, 3.31e-3   fixed-slope level 1: 2.87e-5, 7.40e-2, 6.04e-3
#   p2b level 2 (87.2k DOFs): 1.93e-5, 3.43e-4, 1.28e-3   fixed-slope level 2: 8.46e-6, 4.93e-3, 1.92e-3
#   p2b level 3 (361k DOFs):  1.40e-6, 2.32e-4, 3.19e-4   (the LU kept over the Newton iterations, 101 s)
# Error ratios per level: th 2 -> 3: 4.8, 5.5, 13.6 (fixed-slope 2.6, 1.5, 3.3); p2b 1 -> 2: 12.6,
# 140, 2.6 (fixed-slope 3.4, 15, 3.1); p2b 2 -> 3: 13.8, 1.5, 4.0.  The signed errors of p2b change sign
# for c_L (+4.8e-2, −3.4e-4, +2.3e-4) and Δp (−3.3e-3, −1.3e-3, +3.2e-4): their level-2 values lie near a
# crossing, so only c_D is rated from level 2 to 3 (and c_L over two levels: 208, i.e. 14 per level);
# all three are held by their bounds.  P2 velocities converge at least at second order (ratio 4).
_P2_LEVELS = {
    "th": ((2, 3), {"cd": 1.3e-6, "cl": 4.5e-4, "dp": 6.5e-4}, ("cd", "cl", "dp")),
    "p2b": ((2, 3), {"cd": 3.5e-6, "cl": 5.8e-4, "dp": 8e-4}, ("cd",)),
}


@pytest.mark.parametrize("element", [pytest.param("th", marks=pytest.mark.slow(seconds=58)),
                                     pytest.param("p2b", marks=pytest.mark.slow(seconds=115))])
def test_dfg_2d1_p2_elements_converge_at_second_order(element):
    """P2/P1 and P2+bubble/P1dc from level 2 to 3 on DFG 2D-1: the rated errors fall at least 4x
    per level (second order), and the finer level is within 2.5x of the measured errors above;
    both fail on the fixed-slope meshes (c_D ratios 2.6 and 3.4).  (Seconds measured at a load
    average of ~2 on 2 cores; P2+bubble level 3 needs 4.8 GB.)"""
    (coarse, fine), bound, rated = _P2_LEVELS[element]
    e0 = dfg_2d1(element, coarse).relative_errors()
    e1 = dfg_2d1(element, fine).relative_errors()
    for k in rated:
        assert e0[k] / e1[k] > 4.0, (k, e0[k], e1[k])
    for k, b in bound.items():
        assert e1[k] < b, (k, e1[k])


@pytest.mark.slow(seconds=80)
def test_dfg_2d2_reaches_the_target_accuracy():
    """The case defaults, the cheapest route of the measured front within 0.3 % on St and c_D,max:
    P3/P2 on the level-0 mesh refined at the cylinder (FRONT_2D2, 8.9k DOFs), BDF3 dt = 0.0075,
    semi-implicit, window [4, 6]: measured St +2.02e-3, c_D,max +6.73e-4, c_L,max −2.67e-3 relative
    (26 s on an idle machine).  St and c_D,max are held at the target itself, 0.3 % (1.5x and 4.5x
    the measured), c_L,max at 2.5x."""
    from fluidem.cases.dfg import FRONT_2D2, dfg_2d2

    res = dfg_2d2()
    assert res.level == "0 (h0 0.02, h_max 0.12)" and FRONT_2D2 == {"h0": 0.02, "h_max": 0.12}
    errs = res.relative_errors()
    assert errs["st"] < 3e-3
    assert errs["cd_max"] < 3e-3
    assert errs["cl_max"] < 6.7e-3
    assert res.extra["periods_measured"] >= 5


@pytest.mark.slow(seconds=80)
def test_square_cylinder_re100_against_sohankar():
    """Taylor–Hood level 0 (15k DOFs), dt = 0.05, measured on t ∈ [50, 100] at 5 % blockage with
    free-slip walls: measured St 0.1467 (+0.5 %) and mean C_D 1.514 (+2.4 %) against Sohankar
    et al. (1998) 0.146 and 1.478; the target is 3 % for both.  (Level 1: +1.2 %, +1.8 %.)"""
    from fluidem.cases.square_cylinder import square_cylinder

    res = square_cylinder(level=0, t_end=100.0, window=50.0)
    errs = res.relative_errors()
    assert errs["st"] < 0.03
    assert errs["cd_mean"] < 0.03


@pytest.mark.slow(seconds=150)
def test_dfg_2d3_within_one_percent():
    """P3/P2 level 1 (16.8k DOFs), BDF3 dt = 0.005 (the case defaults), forces normalised with
    Ū = 1: measured c_D,max +2.1e-4, c_L,max +5.0e-3, Δp(8) −2.8e-4 against John (2004); the
    target is 1 % for c_D,max and c_L,max (c_L,max held at 2x its error, the others at ~2.5x)."""
    from fluidem.cases.dfg import dfg_2d3

    res = dfg_2d3()
    errs = res.relative_errors()
    assert errs["cd_max"] < 5e-4
    assert errs["cl_max"] < 1e-2
    assert errs["dp_end"] < 7e-4
    assert abs(res.quantities["t_cd_max"] - 3.93625) < 0.01
