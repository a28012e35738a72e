"""Figures and numbers of the free-body example pages (docs/examples/*.md) from the examples' runs.

Runs ``fluidem run --example NAME`` into ``out/NAME`` (unless that directory already holds a
finished run), reads its ``history.csv`` and draws ``docs/images/example-NAME.png`` against the
reference; prints the figures the pages quote.

* ``settling-disk``: settling speed −v_y(t) against the terminal velocity of steady flows in
  the disk's frame (:func:`fluidem.cases.settling.steady_terminal_velocity`, the same
  parameters); the terminal speed of the run is extrapolated from the samples at t = 3, 3.5
  and 4 (Aitken's Δ², the approach is exponential).
* ``jeffery-orbit``: the angle and angular velocity of the ellipse against Jeffery's (1922)
  orbit in unbounded shear, tan θ = −(1/r) tan(γ̇ r t / (r² + 1)).
* ``sheared-suspension``: the wall shear stress of every step over μ γ̇ with the run's μ_eff/μ
  over its window, and the bodies at the start and the end.
* ``column-collapse-fluid``: the granular step in a viscous liquid and its dry twin
  (``column-collapse-fluid-dry``): the mesh at the start and at the end of the immersed run, the
  deposits side by side, their front and kinetic energy over time, and the figures of the page's
  table (run-out, height, re-triangulations, cost).  A fluid run stopped early (``run.json``
  status ``interrupted``) is used as it is, and the time it reached is printed.

Run from the repository root::

    OPENBLAS_NUM_THREADS=1 MPLBACKEND=Agg python docs/example_figures.py \\
        [settling-disk] [jeffery-orbit] [sheared-suspension] [column-collapse-fluid]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from fluidem.io import read_history  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
IMAGES = ROOT / "docs" / "images"


def ensure_run(name: str, out: Path) -> float | None:
    """Run the example into ``out`` unless a finished run is there; its wall time in s (or None)."""
    from fluidem.cli import main

    import json

    if (out / "run.json").exists() and json.loads((out / "run.json").read_text())["status"] == "complete":
        return None
    t0 = time.perf_counter()
    status = main(["run", "--example", name, "--out", str(out), "--quiet", "--overwrite"])
    if status:
        raise SystemExit(f"fluidem run --example {name} exited with {status}")
    return time.perf_counter() - t0


def aitken(a: float, b: float, c: float) -> float:
    """Limit of an exponentially converging sequence from three equally spaced terms."""
    d = (c - b) - (b - a)
    return c if d == 0 else c - (c - b) ** 2 / d


def terminal_speed(history: dict, times=(3.0, 3.5, 4.0)) -> float:
    """The settling speed extrapolated from −v_y at ``times`` (Aitken's Δ²)."""
    t, v = history["t"], -history["vy"]
    return aitken(*(float(v[np.argmin(np.abs(t - s))]) for s in times))


def settling_disk(out: Path) -> dict:
    import matplotlib.pyplot as plt

    from fluidem.cases.settling import steady_terminal_velocity

    wall = ensure_run("settling-disk", out)
    h = read_history(out)
    t0 = time.perf_counter()
    ref = steady_terminal_velocity(h=0.025, element="p2b")  # the scene's parameters
    t_ref = time.perf_counter() - t0
    U = terminal_speed(h)
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.plot(h["t"], -h["vy"], label="coupled run, −v_y")
    ax.axhline(ref["U"], color="k", ls="--", lw=0.8, label=f"steady reference {ref['U']:.5f}")
    ax.plot([4.0], [U], "o", ms=4, label=f"extrapolated terminal speed {U:.5f}")
    ax.set_xlabel("t")
    ax.set_ylabel("settling speed")
    ax.set_title("settling-disk: ρs/ρf = 1.5, ν = 0.01, a = 0.1, channel width 1")
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    IMAGES.mkdir(parents=True, exist_ok=True)
    fig.savefig(IMAGES / "example-settling-disk.png", dpi=110)
    plt.close(fig)
    return {"run_wall_s": wall, "u_terminal": U, "u_end": float(-h["vy"][-1]), "reference": float(ref["U"]),
            "reference_s": t_ref, "reference_dofs": int(ref["dofs"]), "relative": U / float(ref["U"]) - 1,
            "drift": float(np.abs(h["x"]).max()), "omega_max": float(np.abs(h["omega"]).max())}


def jeffery(t, r=2.0, rate=1.0):
    """Jeffery's (1922) angle (unwrapped, turning clockwise) and angular velocity in unbounded shear."""
    phase = rate * r * t / (r * r + 1)
    theta = -np.arctan2(np.sin(phase), r * np.cos(phase))
    theta = -np.unwrap(-theta)
    omega = -rate * (r * r * np.sin(theta) ** 2 + np.cos(theta) ** 2) / (r * r + 1)
    return theta, omega


def jeffery_orbit(out: Path) -> dict:
    import matplotlib.pyplot as plt

    wall = ensure_run("jeffery-orbit", out)
    h = read_history(out)
    t, ang, om = h["t"], h["angle"], h["omega"]
    r = 2.0
    T_half = np.pi * (r + 1 / r)
    th, omj = jeffery(t, r)
    t_half = float(np.interp(np.pi, -ang, t))
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
    ax[0].plot(t, -ang, label="fluidem, −θ")
    ax[0].plot(t, -th, "k--", lw=0.8, label="Jeffery (unbounded)")
    ax[0].axhline(np.pi, color="grey", lw=0.5)
    ax[0].set_xlabel("γ̇ t")
    ax[0].set_ylabel("−θ (rad)")
    ax[0].legend(fontsize=8)
    ax[0].set_title(f"half period {t_half:.3f} (Jeffery {T_half:.3f})")
    ax[1].plot(t[1:], om[1:], label="fluidem, ω")
    ax[1].plot(t, omj, "k--", lw=0.8, label="Jeffery (unbounded)")
    ax[1].set_xlabel("γ̇ t")
    ax[1].set_ylabel("ω / γ̇")
    ax[1].legend(fontsize=8)
    ax[1].set_title("angular velocity")
    fig.suptitle("jeffery-orbit: ellipse r = 2, a/H = 0.1, Stokes shear cell")
    fig.tight_layout()
    IMAGES.mkdir(parents=True, exist_ok=True)
    fig.savefig(IMAGES / "example-jeffery-orbit.png", dpi=110)
    plt.close(fig)
    return {"run_wall_s": wall, "half_period": t_half, "jeffery": T_half, "relative": t_half / T_half - 1,
            "omega_min": float(om[1:].min()), "omega_max": float(om[1:].max())}


def sheared_suspension(out: Path) -> dict:
    import json

    import matplotlib.pyplot as plt

    from fluidem.cases.scenes import example_scene
    from fluidem.io import read_sides
    from fluidem.rheology import shear_cell, wall_shear_stress

    wall = ensure_run("sheared-suspension", out)
    scene = example_scene("sheared-suspension")
    cell, _ = shear_cell(scene)
    sides = read_sides(out)
    lo, hi = (sides["side"] == s for s in cell.sides)
    F = np.column_stack([sides["fx"], sides["fy"]])
    t = sides["t"][lo]
    ratio = wall_shear_stress(F[lo], F[hi], cell) / (cell.viscosity * cell.shear_rate)
    rh = json.loads((out / "run.json").read_text())["rheology"]
    h = read_history(out)
    fig, ax = plt.subplots(1, 2, figsize=(11, 3.8), gridspec_kw={"width_ratios": [1.3, 1]})
    ax[0].plot(cell.shear_rate * t, ratio, lw=0.8, label="wall shear stress / (μ γ̇), per step")
    t0, t1 = rh["window"]
    mu, se = rh["mu_eff_over_mu"], rh["standard_error"]
    ax[0].hlines(mu, cell.shear_rate * t0, cell.shear_rate * t1, color="C3",
                 label=f"μ_eff/μ = {mu:.3f} ± {se:.3f} (window)")
    ax[0].axhline(1 + 2 * 0.1, color="k", ls="--", lw=0.8, label="1 + 2φ (Einstein, 2D)")
    ax[0].set_xlabel("strain γ̇ t")
    ax[0].set_ylabel("μ_eff / μ")
    ax[0].legend(fontsize=8)
    last = h["step"] == h["step"].max()
    first = h["step"] == h["step"].min()
    for k, (sel, style) in enumerate(((first, dict(facecolor="none", edgecolor="0.6")),
                                      (last, dict(facecolor="C0", edgecolor="C0", alpha=0.7)))):
        for x, y in zip(h["x"][sel], h["y"][sel]):
            for dx in (-2.0, 0.0, 2.0):  # the images across the periodic sides
                ax[1].add_patch(plt.Circle((x + dx, y), 0.0564, **style))
    ax[1].set_xlim(0, 2)
    ax[1].set_ylim(-0.5, 0.5)
    ax[1].set_aspect("equal")
    ax[1].set_title("bodies at t = 0 (outlines) and at the end (filled)", fontsize=9)
    travelled = float(np.abs(h["x_unwrapped"][last] - h["x_unwrapped"][first]).max())
    fig.suptitle("sheared-suspension: 20 free disks, φ = 0.1, Stokes shear cell periodic in x")
    fig.tight_layout()
    IMAGES.mkdir(parents=True, exist_ok=True)
    fig.savefig(IMAGES / "example-sheared-suspension.png", dpi=110)
    plt.close(fig)
    return {"run_wall_s": wall, "mu_eff_over_mu": mu, "standard_error": se, "travelled_max": travelled}


def grain_outlines(scene, history: dict, step: int) -> list:
    """World outlines (n_k, 2) of the scene's bodies at ``step`` of a run's history, length."""
    m = history["step"] == step
    return [b.world_vertices(position=(x, y), angle=a)
            for b, x, y, a in zip(scene.bodies, history["x"][m], history["y"][m], history["angle"][m])]


def deposit_front(outlines, gap: float) -> tuple[float, int]:
    """Front of the deposit against the left wall: the right end of the grains reached from the
    leftmost one through horizontal gaps below ``gap`` (length), and how many grains lie beyond it
    (grains rolling away on their own do not move the front)."""
    spans = sorted((float(v[:, 0].min()), float(v[:, 0].max())) for v in outlines)
    front = spans[0][1]
    for lo, hi in spans[1:]:
        if lo > front + gap:
            break
        front = max(front, hi)
    return front, sum(lo > front for lo, _ in spans)


def collapse_series(scene, history: dict, gap: float) -> dict:
    """Per recorded step: time, deposit front, height of the heap (highest vertex) and the grains'
    kinetic energy (translation and rotation, per unit depth)."""
    import shapely

    polys = [shapely.Polygon(b.world_vertices()) for b in scene.bodies]
    mass = np.array([p.area * b.density for p, b in zip(polys, scene.bodies)])
    inertia = np.array([b.density * _polar_moment(p) for p, b in zip(polys, scene.bodies)])
    out = {k: [] for k in ("t", "front", "beyond", "height", "energy")}
    for step in sorted(set(history["step"].tolist())):
        m = history["step"] == step
        W = grain_outlines(scene, history, step)
        front, beyond = deposit_front(W, gap)
        v2 = history["vx"][m] ** 2 + history["vy"][m] ** 2
        out["t"].append(float(history["t"][m][0]))
        out["front"].append(front)
        out["beyond"].append(beyond)
        out["height"].append(max(float(v[:, 1].max()) for v in W))
        out["energy"].append(float(0.5 * (mass * v2 + inertia * history["omega"][m] ** 2).sum()))
    return {k: np.array(v) for k, v in out.items()}


def _polar_moment(poly) -> float:
    """Polar moment of area of a polygon about its centroid, length⁴."""
    x, y = np.asarray(poly.exterior.coords)[:-1].T
    x, y = x - poly.centroid.x, y - poly.centroid.y
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    c = x * y1 - x1 * y
    return float(abs((c * (x * x + x * x1 + x1 * x1 + y * y + y * y1 + y1 * y1)).sum()) / 12.0)


def run_figures(out: Path) -> dict:
    """Re-triangulations (per 100 steps, by reason), DEM share, wall seconds per step and the time
    reached, from a run directory's run.json and events.log."""
    import json
    import re

    rec = json.loads((out / "run.json").read_text())
    cost = rec["cost"]["seconds"]
    steps = rec["summary"]["steps"]
    reasons: dict = {}
    events = (out / "events.log").read_text() if (out / "events.log").exists() else ""
    for r in re.findall(r"retriangulation reason=(\S+)", events):
        reasons[r] = reasons.get(r, 0) + 1
    n = sum(reasons.values())
    return {"status": rec["status"], "t": rec["t"], "steps": steps, "wall_s": rec["summary"]["wall_s"],
            "s_per_step": rec["summary"]["wall_s"] / max(steps, 1),
            "dem_share": cost.get("dem", cost["bodies"]) / sum(cost.values()), "retriangulations": n,
            "per_100_steps": 100.0 * n / max(steps, 1), "reasons": reasons,
            "dofs": rec["summary"].get("dofs"), "triangles": rec["summary"].get("triangles")}


def column_collapse_fluid(out: Path) -> dict:
    import json

    import matplotlib.pyplot as plt
    import shapely
    from matplotlib.collections import PolyCollection

    from fluidem.cases.scenes import example_scene
    from fluidem.io import read_fields

    dry_out = out.parent / "column-collapse-fluid-dry"
    wall_dry = ensure_run("column-collapse-fluid-dry", dry_out)
    if not (out / "run.json").exists():  # 20–25 min on one core; a run stopped early is used as it is
        ensure_run("column-collapse-fluid", out)
    scene = example_scene("column-collapse-fluid")
    areas = np.array([shapely.Polygon(b.world_vertices()).area for b in scene.bodies])
    gap = 2 * float(np.sqrt(areas.max() / np.pi))  # a grain size, 2 r_max
    wet_h, dry_h = read_history(out), read_history(dry_out)
    wet, dry = collapse_series(scene, wet_h, gap), collapse_series(scene, dry_h, gap)
    L0, H0 = wet["front"][0], wet["height"][0]
    x0, x1, y0, y1 = scene.domain.box
    phi0 = areas.sum() / (L0 * H0)  # of the bounding box of the step

    # the mesh at the start and at the end of the immersed run
    first, last = read_fields(out, 0, full=False), read_fields(out, None, full=False)
    fig, ax = plt.subplots(2, 1, figsize=(9, 4.8))
    for a, mesh, step_t in ((ax[0], first, "t = 0"), (ax[1], last, f"t = {last.field_data['t'][0]:.2f} s")):
        tri = mesh.cells_dict["triangle"]
        a.triplot(mesh.points[:, 0], mesh.points[:, 1], tri, lw=0.15, color="0.3")
        hist_step = 0 if a is ax[0] else int(wet_h["step"].max())
        a.add_collection(PolyCollection(grain_outlines(scene, wet_h, hist_step), facecolor="C1", edgecolor="none"))
        a.set_xlim(x0, 0.8 * x1)
        a.set_ylim(y0, y1)
        a.set_aspect("equal")
        a.set_title(f"{step_t}: {len(tri)} triangles", fontsize=9)
    fig.suptitle("column-collapse-fluid: the graded mesh around the grains (h = 3.8 mm, growth 1.3, "
                 "h_max = 30 mm)", fontsize=10)
    fig.tight_layout()
    IMAGES.mkdir(parents=True, exist_ok=True)
    fig.savefig(IMAGES / "example-column-collapse-fluid-mesh.png", dpi=80)
    plt.close(fig)

    # the deposits, their fronts and kinetic energies
    fig = plt.figure(figsize=(10, 6.2))
    gs = fig.add_gridspec(3, 2, height_ratios=[1, 1, 1.25])
    for k, (h, label, colour) in enumerate(((wet_h, "in the liquid", "C0"), (dry_h, "dry", "C3"))):
        a = fig.add_subplot(gs[k, :])
        a.add_collection(PolyCollection(grain_outlines(scene, h, 0), facecolor="none", edgecolor="0.75", lw=0.4))
        a.add_collection(PolyCollection(grain_outlines(scene, h, int(h["step"].max())), facecolor=colour,
                                        edgecolor="none", alpha=0.8))
        s = wet if h is wet_h else dry
        a.axvline(s["front"][-1], color=colour, lw=0.8, ls="--")
        a.set_xlim(x0, x1)
        a.set_ylim(y0, 0.2)
        a.set_aspect("equal")
        a.set_title(f"{label}, t = {s['t'][-1]:.2f} s: run-out (L − L0)/L0 = {(s['front'][-1] - L0) / L0:.2f}, "
                    f"H/H0 = {s['height'][-1] / H0:.2f} (outlines: t = 0)", fontsize=9)
    a = fig.add_subplot(gs[2, 0])
    a.plot(wet["t"], (wet["front"] - L0) / L0, "C0", label="in the liquid")
    a.plot(dry["t"], (dry["front"] - L0) / L0, "C3", label="dry")
    a.set_xlabel("t [s]")
    a.set_ylabel("(L − L0)/L0")
    a.legend(fontsize=8)
    a = fig.add_subplot(gs[2, 1])
    a.semilogy(wet["t"][1:], wet["energy"][1:], "C0", label="in the liquid")
    a.semilogy(dry["t"][1:], dry["energy"][1:], "C3", label="dry")
    a.set_xlabel("t [s]")
    a.set_ylabel("grains' kinetic energy [J/m]")
    a.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(IMAGES / "example-column-collapse-fluid-deposit.png", dpi=90)
    plt.close(fig)
    wet_run, dry_run = run_figures(out), run_figures(dry_out)
    return {"run_wall_s_dry": wall_dry, "L0": L0, "H0": H0, "phi0": phi0,
            "fluid": {"t": wet["t"][-1], "runout": (wet["front"][-1] - L0) / L0, "H/H0": wet["height"][-1] / H0,
                      "beyond": int(wet["beyond"][-1]), "energy": wet["energy"][-1],
                      "energy_max": float(wet["energy"].max()), **wet_run},
            "dry": {"t": dry["t"][-1], "runout": (dry["front"][-1] - L0) / L0, "H/H0": dry["height"][-1] / H0,
                    "beyond": int(dry["beyond"][-1]), "energy": dry["energy"][-1],
                    "energy_max": float(dry["energy"].max()), **dry_run},
            "run_json": json.dumps(wet_run["reasons"])}


def main(argv) -> None:
    import matplotlib

    matplotlib.use("Agg")
    which = argv or ["settling-disk", "jeffery-orbit", "sheared-suspension", "column-collapse-fluid"]
    for name in which:
        fn = {"settling-disk": settling_disk, "jeffery-orbit": jeffery_orbit,
              "sheared-suspension": sheared_suspension, "column-collapse-fluid": column_collapse_fluid}[name]
        print(name, fn(Path("out") / name), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
