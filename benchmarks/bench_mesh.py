"""Benchmarks of the moving mesh (:mod:`fluidem.mesh`).

* hard case 1 (200 random convex polygons, area fraction 0.5, h = 0.2, about 4.6k nodes):
  cost per physical step of ``drag`` (amortised re-triangulations included: a round is 60
  steps) and of ``regenerate`` (a round is 10 steps), per step and per node;
* a mesh of about 100k nodes (the same packing, h = 0.0335): one relaxation sweep, and one
  re-triangulation of the current nodes (cut-out, contacts, junction points, Triangle CDT)
  without and with the follow-up relaxation and clean-up.

Run (one BLAS thread; wall-clock, so noisy on a shared machine)::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_mesh.py \
        --benchmark-only --benchmark-columns=median,min,rounds -p no:cacheprovider

``extra_info`` holds ``n_nodes``, ``ms_per_step``, ``us_per_node`` and the re-triangulation
count.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from fluidem.cases.packings import RandomMotion, packing  # noqa: E402
from fluidem.mesh import MovingMesh  # noqa: E402
from fluidem.mesh.relax import relax  # noqa: E402


@pytest.fixture(scope="module")
def scene():
    bodies, poses, box = packing(n=200, phi=0.5, sizes=(0.5, 1.5), n_vertices=(3, 8), min_gap=0.01, seed=0)
    motion = RandomMotion(bodies, poses, box, seed=1)
    seq = [motion.step() for _ in range(200)]
    return bodies, poses, box, seq


@pytest.mark.parametrize("strategy,steps", [("drag", 60), ("regenerate", 10)])
def test_case1_step_cost(benchmark, scene, strategy, steps):
    bodies, poses, box, seq = scene
    state = {}

    def setup():
        state["mm"] = MovingMesh(box, bodies, poses, h=0.2, strategy=strategy)
        return (), {}

    def run():
        mm = state["mm"]
        n_re = 0
        for p in seq[:steps]:
            n_re += mm.update(p).retriangulated
        state["n_re"] = n_re

    benchmark.pedantic(run, setup=setup, rounds=5 if strategy == "drag" else 3, iterations=1)
    mm = state["mm"]
    med = benchmark.stats.stats.median / steps
    q = mm.quality()
    benchmark.extra_info.update(n_nodes=len(mm.points), ms_per_step=1e3 * med,
                                us_per_node=1e6 * med / len(mm.points), retriangulations=state["n_re"],
                                min_angle=q.min_angle, max_angle=q.max_angle, frac_above_135=q.frac_above_135)


@pytest.fixture(scope="module")
def big(scene):
    bodies, poses, box, seq = scene
    mm = MovingMesh(box, bodies, poses, h=0.0335, strategy="drag")
    for p in seq[:3]:
        mm.update(p)
    return mm


def test_relaxation_sweep_100k(benchmark, big):
    mm = big
    benchmark.extra_info.update(n_nodes=len(mm.points), n_edges=len(mm.topo.edges))
    benchmark(relax, mm.points, mm.topo, mm.h_node, mm._mobility, 1, mm.relax_params, bounds=mm.box)


@pytest.mark.parametrize("n_relax", [0, None], ids=["cdt-only", "with-relaxation"])
def test_retriangulation_100k(benchmark, big, n_relax):
    mm = big
    benchmark.extra_info.update(n_nodes=len(mm.points))
    benchmark.pedantic(mm.retriangulate, kwargs=dict(n_relax=n_relax), rounds=3, iterations=1)


def test_triangle_alone_100k(benchmark, big):
    """Calibration: Triangle's constrained Delaunay triangulation of the same nodes and segments."""
    import triangle as tr

    mm = big
    pslg = {"vertices": mm.points, "segments": mm.boundary_segments.astype(np.int32)}
    benchmark.extra_info.update(n_nodes=len(mm.points))
    benchmark.pedantic(tr.triangulate, args=(pslg, "pQ"), rounds=5, iterations=1)
