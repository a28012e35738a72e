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

Run from the repository root::

    OPENBLAS_NUM_THREADS=1 MPLBACKEND=Agg python docs/example_figures.py \\
        [settling-disk] [jeffery-orbit] [sheared-suspension]
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


def main(argv) -> None:
    import matplotlib

    matplotlib.use("Agg")
    which = argv or ["settling-disk", "jeffery-orbit", "sheared-suspension"]
    for name in which:
        fn = {"settling-disk": settling_disk, "jeffery-orbit": jeffery_orbit,
              "sheared-suspension": sheared_suspension}[name]
        print(name, fn(Path("out") / name), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
