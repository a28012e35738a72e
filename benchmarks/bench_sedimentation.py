"""Resolved sedimentation of one disk in a closed channel (Glowinski et al. 2001; Wan & Turek 2006).

CGS units (cm, g, s): channel [0, 2] × [0, 6] cm with no-slip walls on all four sides, fluid
density ρ_f = 1 g/cm³, gravity g = 980 cm/s² downwards, a disk of diameter d = 0.25 cm (a regular
polygon of ``segments`` sides) released at rest at (1, 4):

* case B: ρ_s/ρ_f = 1.5, ν = 0.01 cm²/s (the published runs show a lateral oscillation);
* case A: ρ_s/ρ_f = 1.25, ν = 0.1 cm²/s (settles on the centre line), against the terminal
  velocity of :func:`fluidem.cases.settling.steady_terminal_velocity` (steady flows in the disk's
  frame, the same parameters, an independent computation).

The coupled fluid–body solver (:class:`fluidem.coupling.free_flow.FreeBodyFlow`: implicit
coupling, BDF2, semi-implicit convection, P2+bubble/P1dc) moves the disk until the gap to the
floor falls below two mesh sizes (there is no contact or lubrication model in a fluid yet).

Case B's set-up is symmetric about the centre line: a lateral motion can only grow from a
perturbation.  Here the disk is released ``offset`` = d/250 = 0.001 cm to the right of the centre
line (the size of the offsets of Uhlmann's 2005 two-disk variant), so the seed does not depend on
the mesh's round-off asymmetry; ``offset = 0`` runs the published release point.

Reynolds numbers: Re_f = ρ_f |U| d / μ = |U| d / ν (fluid density) and Re_s = ρ_s |U| d / μ
(particle density, the definition the published "maximum particle Reynolds numbers" appear to
use, REFERENCES.md).

Run (case B about 10–30 minutes on this machine, niced; case A a few minutes)::

    OPENBLAS_NUM_THREADS=1 nice python benchmarks/bench_sedimentation.py b
    OPENBLAS_NUM_THREADS=1 nice python benchmarks/bench_sedimentation.py a

Results go to ``benchmarks/results/sedimentation_case_{b,a}.{md,json,png}``;
``python benchmarks/bench_sedimentation.py report b`` redraws them from the stored JSON.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description  # noqa: E402

from fluidem.geometry import regular_polygon  # noqa: E402
from fluidem.scene import Scene  # noqa: E402
from fluidem.simulation import Simulation  # noqa: E402

D = 0.25          # disk diameter, cm
G = 980.0         # cm/s²
CASES = {         # density ratio, ν (cm²/s), h (cm), h_max (cm), dt (s)
    "b": {"density": 1.5, "nu": 0.01, "h": 0.0125, "h_max": 0.1, "dt": 1e-3, "offset": D / 250},
    "a": {"density": 1.25, "nu": 0.1, "h": 0.0125, "h_max": 0.1, "dt": 2e-3, "offset": 0.0},
}


def scene(density, nu, h, h_max, dt, offset=0.0, segments=None, t_end=2.0) -> Scene:
    """The channel and the disk of the module docstring (``t_end`` only bounds the run)."""
    a = 0.5 * D
    segments = segments or max(64, int(np.ceil(np.pi * D / h)))
    return Scene.from_dict({
        "name": "sedimentation", "gravity": [0.0, -G],
        "fluid": {"model": "navier-stokes", "viscosity": nu, "density": 1.0},
        "domain": {"box": [0.0, 2.0, 0.0, 6.0]},
        "bodies": [{"name": "disk", "shape": "polygon", "vertices": regular_polygon(a, segments).tolist(),
                    "position": [1.0 + offset, 4.0], "density": density}],
        "mesh": {"h": h, "grading": {"growth": 1.15, "h_max": h_max}},
        "time": {"dt": dt, "t_end": dt * int(round(t_end / dt))}})


def run(case: str, max_steps: int | None = None, **over) -> dict:
    """Run ``case`` ("a" or "b", parameters of :data:`CASES` overridden by ``over``) until the gap to
    the floor is below 2 h (or ``max_steps``); the trajectory and the summary as a dict."""
    p = {**CASES[case], **over}
    sc = scene(p["density"], p["nu"], p["h"], p["h_max"], p["dt"], p["offset"])
    t0 = time.perf_counter()
    sim = Simulation(sc)
    t_build = time.perf_counter() - t0
    dofs_start = int(sim.flow.dofs)
    cpu0 = time.process_time()
    a = 0.5 * D
    rows, failure = [], None
    n_max = sim.plan.n_steps if max_steps is None else max_steps
    t0 = time.perf_counter()
    while sim.step_index < n_max:
        try:
            sim.run(out_dir=None, n_steps=sim.step_index + 1)
        except Exception as exc:  # a failed step is a result: where and how
            failure = {"step": sim.step_index + 1, "t": (sim.step_index + 1) * p["dt"],
                       "message": f"{type(exc).__name__}: {exc}"}
            break
        x, y, th = sim.flow.poses[0]
        vx, vy, om = sim.flow.body_velocities[0]
        rows.append((sim.t, x, y, th, vx, vy, om))
        if sim.step_index % 25 == 0:
            print(f"step {sim.step_index} t = {sim.t:.4f} s  x = {x:.6f} y = {y:.4f}  v = ({vx:.4g}, {vy:.4g})  "
                  f"wall {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
        if y - a < 2 * p["h"]:
            break
    wall = time.perf_counter() - t0
    cpu = time.process_time() - cpu0
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    tr = np.array(rows).reshape(-1, 7)
    out = {"case": case, "params": p, "dofs": int(sim.flow.dofs), "dofs_start": dofs_start, "steps": len(rows),
           "wall_s": wall, "cpu_s": cpu, "note": f"Load average {load:.1f} at the end of the run.",
           "build_s": t_build, "triangulations": sim.counters["triangulations"], "failure": failure,
           "trajectory": {k: tr[:, i].tolist() for i, k in enumerate(("t", "x", "y", "theta", "vx", "vy", "omega"))},
           "segments": max(64, int(np.ceil(np.pi * D / p["h"])))}
    out.update(summary(tr, p))
    return out


def summary(tr: np.ndarray, p: dict) -> dict:
    """Maximum Reynolds numbers, terminal and maximum speeds, and the lateral oscillation."""
    t, x, y, _, vx, vy, _ = tr.T
    speed = np.hypot(vx, vy)
    k = int(np.argmax(speed))
    re_f = speed[k] * D / p["nu"]
    s = {"t_end": float(t[-1]), "y_end": float(y[-1]), "gap_end": float(y[-1] - 0.5 * D),
         "max_speed": float(speed[k]), "t_max_speed": float(t[k]), "re_max_fluid": float(re_f),
         "re_max_particle": float(p["density"] * re_f)}
    # terminal velocity: the mean settling speed while the centre is 1.5 to 2.5 cm above the floor
    # (6 to 10 d: past the acceleration from 4 cm, before the floor slows the disk), and its spread
    band = (y > 1.5) & (y < 2.5)
    s["u_terminal"] = float(-vy[band].mean()) if band.any() else None
    s["u_terminal_spread"] = float(np.ptp(vy[band])) if band.any() else None
    s["u_band"] = (float(-vy[band][0]), float(-vy[band][-1])) if band.any() else None
    # lateral motion: onset when |x - x_c| first exceeds max(3 × the release offset, 1e-3 d), x_c = 1 the
    # centre line; its extremes are the sign changes of vx after the onset (amplitude: the largest
    # |x - x_c| there; period: twice the mean spacing of the extremes, when there are three or more)
    dev = x - 1.0
    onset = np.flatnonzero(np.abs(dev) > max(3 * abs(p["offset"]), 1e-3 * D))
    s["lateral_max"] = float(np.abs(dev).max())
    s["lateral_onset_t"] = float(t[onset[0]]) if onset.size else None
    ext = np.flatnonzero(np.sign(vx[1:]) != np.sign(vx[:-1])) + 1
    ext = ext[ext >= onset[0]] if onset.size else ext[:0]
    s["lateral_extremes"] = [(float(t[i]), float(dev[i])) for i in ext]
    s["lateral_period"] = float(2 * np.diff(t[ext]).mean()) if ext.size >= 3 else None
    s["lateral_amplitude"] = float(np.abs(dev[ext]).max()) if ext.size else None
    s["max_lateral_speed"] = float(np.abs(vx).max())
    return s


def reference(p: dict) -> dict:
    """Terminal velocity of steady flows in the disk's frame (same parameters, CGS)."""
    from fluidem.cases.settling import steady_terminal_velocity

    t0 = time.perf_counter()
    seg = max(64, int(np.ceil(np.pi * D / p["h"])))
    r = steady_terminal_velocity(a=0.5 * D, half_width=1.0, density=p["density"], nu=p["nu"], g=G, h=p["h"],
                                 segments=seg, length=3.0)
    r["wall_s"] = time.perf_counter() - t0
    return r


def plot(res: dict, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tr = res["trajectory"]
    t, x, y, vx, vy = (np.array(tr[k]) for k in ("t", "x", "y", "vx", "vy"))
    fig, ax = plt.subplots(1, 3, figsize=(12, 3.8))
    ax[0].plot(t, x, label="x (cm)")
    ax[0].set_xlabel("t (s)")
    ax[0].set_ylabel("x (cm)")
    ax[0].set_title("lateral position")
    ax[1].plot(t, -vy, label="settling speed −v_y")
    ax[1].plot(t, vx, label="v_x")
    if res.get("reference"):
        ax[1].axhline(res["reference"]["U"], color="k", ls="--", lw=0.8, label="steady reference")
    ax[1].set_xlabel("t (s)")
    ax[1].set_ylabel("cm/s")
    ax[1].legend(fontsize=8)
    ax[1].set_title("velocity")
    ax[2].plot(x, y)
    ax[2].set_xlim(0, 2)
    ax[2].set_ylim(0, 6)
    ax[2].set_aspect("equal")
    ax[2].set_xlabel("x (cm)")
    ax[2].set_ylabel("y (cm)")
    ax[2].set_title("trajectory")
    p = res["params"]
    fig.suptitle(f"case {res['case'].upper()}: ρs/ρf = {p['density']:g}, ν = {p['nu']:g} cm²/s, h = {p['h']:g} cm, "
                 f"dt = {p['dt']:g} s, {res['dofs']} DOFs")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write(res: dict) -> None:
    name = f"sedimentation_case_{res['case']}"
    RESULTS.mkdir(exist_ok=True)
    machine = machine_description()
    (RESULTS / f"{name}.json").write_text(json.dumps({"machine": machine, "rows": [res]}, indent=1,
                                                     default=lambda o: o.item()))
    plot(res, RESULTS / f"{name}.png")
    p = res["params"]
    onset = "none" if res["lateral_onset_t"] is None else f"t = {res['lateral_onset_t']:.4f} s"
    extremes = ", ".join(f"({a:.3f}, {b:+.2e})" for a, b in res["lateral_extremes"]) or "none"
    amplitude = "none" if res["lateral_amplitude"] is None else f"{res['lateral_amplitude']:.3g} cm"
    period = (f"{res['lateral_period']:.3g} s" if res["lateral_period"] is not None else
              "not measurable (fewer than three extremes before the floor)")
    u0, u1 = res["u_band"]
    if res["u_terminal_spread"] > 0.01 * res["u_terminal"]:
        terminal = (f"no terminal state: −v_y rises from {u0:.4f} to {u1:.4f} cm/s across it (mean "
                    f"{res['u_terminal']:.4f})")
    else:
        terminal = (f"terminal speed {res['u_terminal']:.5f} cm/s (mean of −v_y; it varies by "
                    f"{res['u_terminal_spread']:.2g} cm/s across the band)")
    cpu = f", CPU time {res['cpu_s']:.0f} s" if "cpu_s" in res else ""
    dofs = f"{res['dofs_start']} DOFs at the start, {res['dofs']} at the end" if "dofs_start" in res else \
        f"{res['dofs']} DOFs at the end"
    lines = [f"# Sedimentation of one disk, case {res['case'].upper()} (Glowinski et al. 2001; Wan & Turek 2006)", "",
             f"Machine: {machine}; run niced beside other jobs.", "",
             f"Channel 2 × 6 cm, closed; disk d = {D} cm ({res['segments']}-gon) released at rest at "
             f"({1 + p['offset']:g}, 4); ρs/ρf = {p['density']:g}, ν = {p['nu']:g} cm²/s, g = {G:g} cm/s²; "
             f"P2+bubble/P1dc, h = {p['h']:g} cm at the disk graded to {p['h_max']:g} cm, dt = {p['dt']:g} s, "
             f"{dofs}, {res['steps']} steps, {res['triangulations']} triangulations, "
             f"wall time {res['wall_s']:.0f} s{cpu} (`benchmarks/bench_sedimentation.py`).", "",
             "| quantity | value |", "|---|---|",
             f"| stopped at | t = {res['t_end']:.4f} s, gap to the floor {res['gap_end']:.4f} cm |",
             f"| maximum speed | {res['max_speed']:.4f} cm/s at t = {res['t_max_speed']:.4f} s |",
             f"| max Re, fluid density (ρf U d/μ) | {res['re_max_fluid']:.2f} |",
             f"| max Re, particle density (ρs U d/μ) | {res['re_max_particle']:.2f} |",
             f"| settling speed for 1.5 < y < 2.5 cm | {terminal} |",
             f"| largest lateral excursion \\|x − 1\\| | {res['lateral_max']:.4g} cm |",
             f"| lateral onset (\\|x − 1\\| > max(3 offset, 0.001 d)) | {onset} |",
             f"| extremes of x − 1 after the onset (t s, cm) | {extremes} |",
             f"| largest lateral speed \\|v_x\\| | {res['max_lateral_speed']:.4g} cm/s |",
             f"| lateral amplitude, period after onset | {amplitude}, {period} |"]
    if res.get("reference"):
        r = res["reference"]
        lines.append(f"| steady reference terminal speed | {r['U']:.5f} cm/s ({r['dofs']} DOFs, {r['iterations']} "
                     f"solves, {r['wall_s']:.0f} s); peak speed / steady − 1 = "
                     f"{res['max_speed'] / r['U'] - 1:+.2e}, band mean / steady − 1 = "
                     f"{res['u_terminal'] / r['U'] - 1:+.2e} |")
    if res["failure"]:
        f = res["failure"]
        lines.append(f"| failure | step {f['step']}, t = {f['t']:.4f} s: {f['message']} |")
    if res.get("note"):
        lines += ["", res["note"]]
    lines += ["", f"![case {res['case'].upper()}]({name}.png)", ""]
    (RESULTS / f"{name}.md").write_text("\n".join(lines))


def report(case: str) -> dict:
    """Recompute the summary of a stored run (``results/sedimentation_case_{case}.json``) and rewrite
    its .md and .png."""
    res = json.loads((RESULTS / f"sedimentation_case_{case}.json").read_text())["rows"][0]
    tr = np.array([res["trajectory"][k] for k in ("t", "x", "y", "theta", "vx", "vy", "omega")]).T
    res.update(summary(tr, res["params"]))
    write(res)
    return res


def main(argv) -> None:
    if argv and argv[0] == "report":
        res = report(argv[1])
        print(json.dumps({k: v for k, v in res.items() if k not in ("trajectory", "lateral_extremes")}, indent=1,
                         default=str))
        return
    case = argv[0] if argv else "b"
    max_steps = int(argv[1]) if len(argv) > 1 else None
    res = run(case, max_steps=max_steps)
    if case == "a":
        res["reference"] = reference(res["params"])
    if max_steps is None:
        write(res)
    print(json.dumps({k: v for k, v in res.items() if k not in ("trajectory", "lateral_extremes")}, indent=1,
                     default=str))


if __name__ == "__main__":
    main(sys.argv[1:])
