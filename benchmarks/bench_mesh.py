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

Collective motion (hard case 6, :func:`fluidem.cases.packings.collective_motion`, written to
``benchmarks/results/mesh_collective.{md,json}``; about 5 minutes): 120 polygons at area
fraction 0.3 in a 10 × 10 box, h = 0.08, moved as a whole (rotation, breathing, shear; one
period of 300 steps; dense packings turned and scaled, ``COLLECTIVE_ROWS``), ``drag`` over
the period against ``regenerate`` over its first 30 steps,
and hard case 1 (60 drag steps, 30 regenerate steps) in the same run for the per-node cost.
Per step: wall time split by stage, re-triangulations by reason, the worst angles in narrow
gaps, near the bodies (centroid within 2 h of an outline) and in the open fluid.
Targets: drag ≥ 5 × cheaper per step than regenerate (means, re-triangulations amortised),
per-node cost ≤ 1.5 × hard case 1's, minimum angle outside narrow gaps ≥ 15°, ≤ 1 % of the
angles above 135°.  Dense cases (area fraction 0.32, gaps 0.01–0.03 < h/2, turned and scaled
until the narrowest gap nearly closes or one pair touches): ≥ 5 ×, ≥ 10° outside narrow gaps,
narrow gaps as a fresh triangulation makes them.  Only this part::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_mesh.py -k collective --benchmark-only -p no:cacheprovider
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402
import shapely  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

from fluidem.cases.packings import RandomMotion, collective_motion, packing  # noqa: E402
from fluidem.mesh import MovingMesh  # noqa: E402
from fluidem.mesh import drag_step as drag_step_module  # noqa: E402
from fluidem.mesh import moving_triangulation as triangulation_module  # noqa: E402
from fluidem.mesh.quality import triangle_angles  # noqa: E402
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


# ---------------------------------------------------------------- hard case 6: collective motion
#: stages of a drag step timed by :class:`StageTimer` (functions called by fluidem.mesh.moving)
STAGES = {"drag": "dragged_positions", "relax": "relax", "triggers": "retriangulation_reason",
          "history": None, "retriangulate": None, "harmonic_factor": None}
#: the rows: (label, motion kind, arguments of :func:`collective_motion` besides ``h``)
COLLECTIVE_ROWS = (
    ("rotation", "rotation", {}),
    ("breathing", "breathing", {}),
    ("shear", "shear", {}),
    # the first dense case: gaps 0.01-0.03 scaled by 5 %, so that 40 pairs overlap by up to 0.013
    # (1.3 times the narrowest start gap, h/6), more than bodies of a suspension do
    ("turn-and-breathe", "turn-and-breathe", {"min_gap": 0.01}),
    # dense packings moved as a suspension can move: area fraction 0.32, gaps 0.01-0.03 (h/8 to
    # h/2.7), turned by 0.25 rad and scaled by 2 % (the narrowest gap closes to 0.0012, h/67, no
    # overlap) or by 2.5 % (one pair comes into contact, overlapping by 0.0012 as a soft DEM
    # contact does)
    ("dense, near contact", "turn-and-breathe", {"phi": 0.32, "min_gap": 0.01, "amplitude": (0.25, 0.02)}),
    ("dense, into contact", "turn-and-breathe", {"phi": 0.32, "min_gap": 0.01, "amplitude": (0.25, 0.025)}),
)
COLLECTIVE_H = 0.08
REGENERATE_STEPS = 30


class StageTimer:
    """Wall time spent in the stages of :meth:`MovingMesh.update` (wrappers installed for a run)."""

    def __init__(self):
        self.seconds = dict.fromkeys(STAGES, 0.0)
        self._saved = []
        self._in_retriangulation = False

    def _wrap(self, owner, name, stage):
        fn = getattr(owner, name)
        self._saved.append((owner, name, fn))

        def timed(*a, **k):
            # the stages called inside a re-triangulation count as re-triangulation
            nested = self._in_retriangulation and stage != "retriangulate"
            self._in_retriangulation |= stage == "retriangulate"
            t0 = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                if not nested:
                    self.seconds[stage] += time.perf_counter() - t0
                if stage == "retriangulate":
                    self._in_retriangulation = False

        setattr(owner, name, timed)

    def __enter__(self):
        for stage, name in STAGES.items():
            if name is not None:
                # the drag step's stages; relax also in the triangulation (counted there as re-triangulation)
                for module in (drag_step_module, triangulation_module):
                    if hasattr(module, name):
                        self._wrap(module, name, stage)
        self._wrap(MovingMesh, "_carry_history", "history")
        self._wrap(MovingMesh, "retriangulate", "retriangulate")
        self._wrap(drag_step_module, "harmonic_drag", "harmonic_factor")
        return self

    def __exit__(self, *exc):
        for owner, name, fn in reversed(self._saved):
            setattr(owner, name, fn)


def angle_census(mm, q_narrow, near_tree, h):
    """Worst min angle / share above 135° in narrow gaps, near the bodies and in the open fluid."""
    ang = triangle_angles(mm.points, mm.triangles)
    amin, amax = ang.min(axis=1), ang.max(axis=1)
    d, _ = near_tree(mm).query(mm.points[mm.triangles].mean(axis=1))
    near = d < 2 * h
    out = {}
    for name, sel in (("narrow", q_narrow), ("near", ~q_narrow & near), ("open", ~q_narrow & ~near)):
        out[name] = (float(amin[sel].min()) if sel.any() else 90.0, int((amax[sel] > 135).sum()), int(sel.sum()))
    return out


def run_motion(box, bodies, poses0, seq, h, strategy, census=True):
    """Update through ``seq``; per-step times, stage times, reasons and angle statistics."""
    mm = MovingMesh(box, bodies, poses0, h=h, strategy=strategy)
    times, cpu, reasons, nodes = [], [], {}, []
    worst = {"narrow": 90.0, "near": 90.0, "open": 90.0}
    above = {"narrow": 0.0, "near": 0.0, "open": 0.0}
    seen = {"narrow": 0, "near": 0, "open": 0}  # most triangles in the region in one step
    worst_outside, worst_135 = 90.0, 0.0

    def tree(mm):
        return cKDTree(mm.outlines.world(mm.poses))

    with StageTimer() as timer:
        for p in seq:
            t0, c0 = time.perf_counter(), time.process_time()
            ev = mm.update(p)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            reasons[ev.reason] = reasons.get(ev.reason, 0) + 1
            nodes.append(len(mm.points))
            if census:
                narrow = mm._narrow_gap()
                q = mm.quality()
                assert q.n_inverted == 0 and q.n_nodes_inside_bodies == 0
                worst_outside = min(worst_outside, q.min_angle)
                worst_135 = max(worst_135, q.frac_above_135)
                for name, (a, n_above, n_tri) in angle_census(mm, narrow, tree, h).items():
                    worst[name] = min(worst[name], a)
                    above[name] = max(above[name], n_above / max(n_tri, 1))
                    seen[name] = max(seen[name], n_tri)
    t = np.array(times)
    n_nodes = float(np.mean(nodes))
    return {"strategy": strategy, "steps": len(t), "n_nodes": n_nodes, "mean_ms": 1e3 * t.mean(),
            "median_ms": 1e3 * float(np.median(t)),
            "cpu_mean_ms": 1e3 * float(np.mean(cpu)), "us_per_node_mean": 1e6 * t.mean() / n_nodes,
            "us_per_node_median": 1e6 * float(np.median(t)) / n_nodes, "reasons": reasons,
            "stage_ms_per_step": {k: 1e3 * v / len(t) for k, v in timer.seconds.items()},
            "relax_sweeps_per_step": mm.relax_iterations,
            "worst_min_angle": worst_outside, "worst_frac_above_135": worst_135,
            "worst_min_angle_by_region": worst, "worst_frac_above_135_by_region": above,
            "max_triangles_by_region": seen}


def deepest_overlap(m) -> float:
    """Deepest overlap of two bodies of ``m`` (:class:`CollectiveMotion`) over the period (every
    step), length units: the narrower side of the smallest rectangle around each intersection."""
    worst = 0.0
    for k in range(m.n_steps + 1):
        polys = shapely.polygons(shapely.linearrings(m._world(m.poses_at(k)), indices=m._vb))
        a, b = shapely.STRtree(polys).query(polys, predicate="intersects")
        sel = a < b
        if sel.any():
            rect = shapely.minimum_rotated_rectangle(shapely.intersection(polys[a[sel]], polys[b[sel]]))
            c = shapely.get_coordinates(rect).reshape(-1, 5, 2)
            side = np.minimum(np.linalg.norm(c[:, 1] - c[:, 0], axis=1), np.linalg.norm(c[:, 2] - c[:, 1], axis=1))
            worst = max(worst, float(side.max()))
    return worst


def fresh_at_narrowest(m) -> dict:
    """Angles of a fresh triangulation at the step of the narrowest gap of ``m``: what a new mesh
    gives in the narrow gaps there (the limit set by the outline spacing h across a gap g ≪ h)."""
    gaps = [m._min_gap(m.poses_at(k)) for k in range(m.n_steps + 1)]
    k = int(np.argmin(gaps))
    mm = MovingMesh(m.box, m.bodies, m.poses_at(k), h=COLLECTIVE_H, strategy="drag")
    narrow = mm._narrow_gap()
    amin = triangle_angles(mm.points, mm.triangles).min(axis=1)
    return {"step": k, "gap": gaps[k], "narrow_min_angle": float(amin[narrow].min()) if narrow.any() else 90.0,
            "outside_min_angle": float(amin[~narrow].min())}


def measure_collective() -> list:
    rows = []
    bodies, poses, box = packing(n=200, phi=0.5, sizes=(0.5, 1.5), n_vertices=(3, 8), min_gap=0.01, seed=0)
    motion = RandomMotion(bodies, poses, box, seed=1)
    seq = [motion.step() for _ in range(60)]
    rows.append({"case": "hard case 1", "h": 0.2, "rim_step": None, "min_gap_seen": None,
                 "drag": run_motion(box, bodies, poses, seq, 0.2, "drag", census=False),
                 "regenerate": run_motion(box, bodies, poses, seq[:REGENERATE_STEPS], 0.2, "regenerate",
                                          census=False)})
    for label, kind, kwargs in COLLECTIVE_ROWS:
        m = collective_motion(kind, h=COLLECTIVE_H, **kwargs)
        seq = m.sequence()
        rows.append({"case": label, "kind": kind, "h": COLLECTIVE_H, "rim_step": m.rim_step,
                     "min_gap_seen": m.min_gap_seen, "amplitude": m.amplitude, "packing": kwargs,
                     "deepest_overlap": deepest_overlap(m), "fresh_at_narrowest": fresh_at_narrowest(m),
                     "drag": run_motion(m.box, m.bodies, m.poses0, seq, COLLECTIVE_H, "drag"),
                     "regenerate": run_motion(m.box, m.bodies, m.poses0, seq[:REGENERATE_STEPS], COLLECTIVE_H,
                                              "regenerate", census=False)})
    ref = rows[0]["drag"]["us_per_node_mean"]
    for r in rows:
        r["ratio_mean"] = r["regenerate"]["mean_ms"] / r["drag"]["mean_ms"]
        r["ratio_median"] = r["regenerate"]["median_ms"] / r["drag"]["median_ms"]
        r["ratio_cpu_mean"] = r["regenerate"]["cpu_mean_ms"] / r["drag"]["cpu_mean_ms"]
        r["per_node_vs_case1"] = r["drag"]["us_per_node_mean"] / ref
    return rows


def write_collective(rows: list) -> None:
    machine = machine_description()
    write_json("mesh_collective", machine, rows)
    lines = ["# Moving mesh under collective motion (hard case 6)", "", f"Machine: {machine}; one BLAS thread.", "",
             "120 convex polygons (sizes 0.3–0.6, area fraction 0.3 in their own square, centred in a 10 × 10 box), "
             "h = 0.08, one period of 300 steps of a rigid rotation (rim step h/8), a ±5 % breathing of the centre "
             "positions and a simple shear of amplitude 0.1, packed with gaps 0.06–0.18 so that none closes; "
             "`turn-and-breathe`: 0.25 rad and 5 % together on a packing with gaps 0.01–0.03, which overlap "
             "(40 pairs, up to 1.3 times the narrowest start gap: not a target case, kept for comparison); "
             "the dense cases: area fraction 0.32, gaps 0.01–0.03 (all below h/2), 0.25 rad with 2 % (`near "
             "contact`: the narrowest gap closes to h/67, no overlap) or 2.5 % (`into contact`: one pair "
             "touches, overlapping by h/67 as a soft contact does). `drag` over the period, `regenerate` over "
             "its first "
             f"{REGENERATE_STEPS} steps, hard case 1 (200 polygons, h = 0.2, 60 drag / {REGENERATE_STEPS} "
             "regenerate steps) in the same run (`benchmarks/bench_mesh.py`). Means include the "
             "re-triangulations (amortised); "
             "the CPU-time ratio (process time) is less sensitive to other load on the machine.", "",
             "| case | nodes | drag mean ms | drag median ms | regenerate mean ms | ratio (mean) | ratio (median) | "
             "ratio (CPU time, mean) | drag µs/node (mean) | vs case 1 | re-triangulations | "
             "worst min angle outside narrow gaps | worst share > 135° |", "|---" * 13 + "|"]
    for r in rows:
        d, g = r["drag"], r["regenerate"]
        re = ", ".join(f"{k} {v}" for k, v in sorted(d["reasons"].items()) if k) or "none"
        ang = (f"{d['worst_min_angle']:.1f}°" if "worst_min_angle" in d and r["case"] != "hard case 1" else "–")
        frac = (f"{100 * d['worst_frac_above_135']:.3f} %" if r["case"] != "hard case 1" else "–")
        lines.append(f"| {r['case']} | {d['n_nodes']:.0f} | {d['mean_ms']:.1f} | {d['median_ms']:.1f} | "
                     f"{g['mean_ms']:.0f} | {r['ratio_mean']:.1f} | {r['ratio_median']:.1f} | "
                     f"{r['ratio_cpu_mean']:.1f} | "
                     f"{d['us_per_node_mean']:.2f} | {r['per_node_vs_case1']:.2f} | {re} | {ang} | {frac} |")
    lines += ["", "Where the time of a drag step goes (ms per step, means over the run; `retriangulate` includes "
              "its relaxation, `harmonic_factor` is the factorisation of the harmonic extension on the first step "
              "after each triangulation):", "",
              "| case | " + " | ".join(STAGES) + " | relaxation sweeps per step |", "|---" * (len(STAGES) + 2) + "|"]
    for r in rows:
        st = r["drag"]["stage_ms_per_step"]
        lines.append(f"| {r['case']} | " + " | ".join(f"{st[k]:.1f}" for k in STAGES)
                     + f" | {r['drag']['relax_sweeps_per_step']} |")
    lines += ["", "Where the bad angles are (worst min angle over every step and the largest share of angles above "
              "135° in one step, by region; near: centroid within 2 h of a body outline; narrow gaps: gap "
              "below h/2 at the centroid or anchored across one, `MovingMesh.quality`). A gap g ≪ h is "
              "spanned by one layer of elements between outline nodes h apart, whose smallest angle is about "
              "atan(2g/h) however the mesh is made: the last column is a fresh triangulation at the step of "
              "the narrowest gap (or of the first contact):", "",
              "| case | smallest gap (deepest overlap) | narrow gaps | near the bodies | open fluid | "
              "fresh triangulation there: narrow gaps, elsewhere |", "|---" * 6 + "|"]
    for r in rows[1:]:
        w, a = r["drag"]["worst_min_angle_by_region"], r["drag"]["worst_frac_above_135_by_region"]
        n = r["drag"]["max_triangles_by_region"]
        f = r["fresh_at_narrowest"]
        lines.append(f"| {r['case']} | {r['min_gap_seen']:.4f} ({r['deepest_overlap']:.4f}) | "
                     + " | ".join(f"{w[k]:.1f}°, {100 * a[k]:.2f} % (≤ {n[k]} triangles)"
                                  if n[k] else "none" for k in ("narrow", "near", "open"))
                     + f" | {f['narrow_min_angle']:.1f}°, {f['outside_min_angle']:.1f}° (step {f['step']}) |")
    (RESULTS / "mesh_collective.md").write_text("\n".join(lines) + "\n")


def test_collective_motion_cost(benchmark):
    rows = benchmark.pedantic(measure_collective, rounds=1, iterations=1)
    write_collective(rows)
    for r in rows[1:]:
        benchmark.extra_info[r["case"]] = {"ratio_mean": r["ratio_mean"], "per_node_vs_case1": r["per_node_vs_case1"]}
    assert all(r["drag"]["steps"] == 300 for r in rows[1:])


if __name__ == "__main__":
    rows = measure_collective()
    write_collective(rows)
    print((RESULTS / "mesh_collective.md").read_text())
