"""Resolved sedimentation of one disk in a closed channel (Glowinski et al. 2001; Wan & Turek 2006).

CGS units (cm, g, s): channel [0, 2] × [0, 6] cm with no-slip walls on all four sides, fluid
density ρ_f = 1 g/cm³, gravity g = 980 cm/s² downwards, a disk of diameter d = 0.25 cm (a regular
polygon of ``segments`` sides) released at rest at (1, 4):

* case B: ρ_s/ρ_f = 1.5, ν = 0.01 cm²/s (the published runs show a lateral oscillation);
* case A: ρ_s/ρ_f = 1.25, ν = 0.1 cm²/s (settles on the centre line), against the terminal
  velocity of :func:`fluidem.cases.settling.steady_terminal_velocity` (steady flows in the disk's
  frame, the same parameters, an independent computation);
* case B tall (``b-tall``): case B in a closed channel 2 cm wide and 20 cm high, the disk released
  at (1 + d/250, 18), so that the lateral oscillation has room to establish itself (in the 6 cm
  channel the disk reaches the floor after one lateral excursion).

The coupled fluid–body solver (:class:`fluidem.coupling.free_flow.FreeBodyFlow`: implicit
coupling, BDF2, semi-implicit convection, P2+bubble/P1dc) moves the disk until the gap to the
floor falls below two mesh sizes (there is no contact or lubrication model in a fluid yet).

Case B's set-up is symmetric about the centre line: a lateral motion can only grow from a
perturbation.  Here the disk is released ``offset`` = d/250 = 0.001 cm to the right of the centre
line (the size of the offsets of Uhlmann's 2005 two-disk variant), so the seed does not depend on
the mesh's round-off asymmetry; ``offset = 0`` runs the published release point.

The lateral motion is summarised by its onset, the extremes of x − 1 (sign changes of v_x after the
onset, ignoring swings smaller than the onset threshold), the amplitude (the largest |x − 1| at
an extreme, and half the last peak-to-peak swing), the period (twice the mean spacing of the
extremes, from three extremes on, while the centre is more than ``FLOOR`` = 2.5 cm = 10 d above the
floor) and the Strouhal number St = f d / U, f = 1/period and U the mean settling speed −v_y
between the first and the last of those extremes; the same again over the last (up to) four full periods,
the established oscillation.  Whether the settling speed reaches a terminal
(steady mean) value is judged from its means over successive full periods (each the span of three
consecutive extremes): terminal when the last two differ by less than ``TERMINAL_TOL`` = 0.5 %.

Reynolds numbers: Re_f = ρ_f |U| d / μ = |U| d / ν (fluid density) and Re_s = ρ_s |U| d / μ
(particle density, the definition the published "maximum particle Reynolds numbers" appear to
use, REFERENCES.md).

Run (case B about 10–30 minutes on this machine, niced; case A a few minutes; case B tall about
75 minutes, 67 min of CPU)::

    OPENBLAS_NUM_THREADS=1 nice python benchmarks/bench_sedimentation.py b
    OPENBLAS_NUM_THREADS=1 nice python benchmarks/bench_sedimentation.py a
    OPENBLAS_NUM_THREADS=1 nice python benchmarks/bench_sedimentation.py b-tall

(a second argument, a number of steps, makes a check run that writes nothing).  Results go to
``benchmarks/results/sedimentation_case_{b,a,b_tall}.{md,json,png}``;
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
FLOOR = 2.5       # cm: extremes used for the period and the Strouhal number lie above this height (10 d)
TERMINAL_TOL = 5e-3  # relative change of the per-period mean settling speed below which it is terminal
CASES = {         # density ratio, ν (cm²/s), h (cm), h_max (cm), dt (s); channel height and release height (cm)
    "b": {"density": 1.5, "nu": 0.01, "h": 0.0125, "h_max": 0.1, "dt": 1e-3, "offset": D / 250},
    "a": {"density": 1.25, "nu": 0.1, "h": 0.0125, "h_max": 0.1, "dt": 2e-3, "offset": 0.0},
    "b-tall": {"density": 1.5, "nu": 0.01, "h": 0.0125, "h_max": 0.1, "dt": 1e-3, "offset": D / 250,
               "height": 20.0, "release": 18.0, "t_end": 4.0},
}


def scene(density, nu, h, h_max, dt, offset=0.0, segments=None, t_end=2.0, height=6.0, release=4.0) -> Scene:
    """The channel (2 cm × ``height``) and the disk (released at rest at (1 + ``offset``, ``release``))
    of the module docstring (``t_end`` only bounds the run)."""
    a = 0.5 * D
    segments = segments or max(64, int(np.ceil(np.pi * D / h)))
    return Scene.from_dict({
        "name": "sedimentation", "gravity": [0.0, -G],
        "fluid": {"model": "navier-stokes", "viscosity": nu, "density": 1.0},
        "domain": {"box": [0.0, 2.0, 0.0, height]},
        "bodies": [{"name": "disk", "shape": "polygon", "vertices": regular_polygon(a, segments).tolist(),
                    "position": [1.0 + offset, release], "density": density}],
        "mesh": {"h": h, "grading": {"growth": 1.15, "h_max": h_max}},
        "time": {"dt": dt, "t_end": dt * int(round(t_end / dt))}})


def run(case: str, max_steps: int | None = None, **over) -> dict:
    """Run ``case`` ("a", "b" or "b-tall", parameters of :data:`CASES` overridden by ``over``) until the
    gap to the floor is below 2 h (or ``max_steps``); the trajectory and the summary as a dict."""
    p = {**CASES[case], **over}
    sc = scene(p["density"], p["nu"], p["h"], p["h_max"], p["dt"], p["offset"], t_end=p.get("t_end", 2.0),
               height=p.get("height", 6.0), release=p.get("release", 4.0))
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
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    tr = np.array(rows).reshape(-1, 7)
    out = {"case": case, "params": p, "dofs": int(sim.flow.dofs), "dofs_start": dofs_start, "steps": len(rows),
           "wall_s": wall, "cpu_s": cpu, "load_end": list(load),
           "note": f"Load average {load[0]:.1f} (1 min), {load[1]:.1f} (5 min), {load[2]:.1f} (15 min) at the end "
                   "of the run.",
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
    # the settling speed every 0.1 s (and the height there)
    dt = float(p["dt"])
    every = max(1, int(round(0.1 / dt)))
    s["settling_history"] = [(float(t[i]), float(y[i]), float(-vy[i])) for i in range(every - 1, len(t), every)]
    # lateral motion: onset when |x - x_c| first exceeds thr = max(3 × the release offset, 1e-3 d), x_c = 1
    # the centre line; its extremes are the sign changes of vx after the onset, kept alternating
    # (a maximum follows a minimum) and ignoring swings smaller than thr (jitter of vx about 0)
    dev = x - 1.0
    thr = max(3 * abs(p["offset"]), 1e-3 * D)
    onset = np.flatnonzero(np.abs(dev) > thr)
    s["lateral_max"] = float(np.abs(dev).max())
    s["lateral_onset_t"] = float(t[onset[0]]) if onset.size else None
    right = vx > 0
    cand = np.flatnonzero(right[1:] != right[:-1]) + 1
    cand = cand[cand >= onset[0]] if onset.size else cand[:0]
    kept: list[tuple[int, int]] = []  # (index, +1 for a maximum of x, -1 for a minimum)
    for i in cand:
        kind = 1 if right[i - 1] else -1
        if kept and kept[-1][1] == kind:  # two of a kind (a skipped small swing between): keep the larger
            if kind * dev[i] > kind * dev[kept[-1][0]]:
                kept[-1] = (int(i), kind)
            continue
        if kept and abs(dev[i] - dev[kept[-1][0]]) < thr:
            continue
        kept.append((int(i), kind))
    ext = np.array([i for i, _ in kept], dtype=int)
    s["lateral_extremes"] = [(float(t[i]), float(dev[i])) for i in ext]
    s["lateral_amplitude"] = float(np.abs(dev[ext]).max()) if ext.size else None
    s["max_lateral_speed"] = float(np.abs(vx).max())
    # period and Strouhal number from the extremes above FLOOR (clear of the floor's influence)
    free = ext[y[ext] > FLOOR]
    s["lateral_extremes_free"] = int(free.size)
    s["lateral_period"] = float(2 * np.diff(t[free]).mean()) if free.size >= 3 else None
    s["lateral_half_periods"] = np.diff(t[free]).tolist()
    # the established oscillation: the last (up to) four full periods, clear of the transient after the onset
    s["lateral_period_last"] = float(2 * np.diff(t[free[-9:]]).mean()) if free.size >= 3 else None
    if free.size >= 2:  # half the last peak-to-peak swing, and its centre
        s["lateral_amplitude_last"] = float(0.5 * abs(dev[free[-1]] - dev[free[-2]]))
        s["lateral_centre_last"] = float(0.5 * (dev[free[-1]] + dev[free[-2]]))
    else:
        s["lateral_amplitude_last"] = s["lateral_centre_last"] = None
    if free.size >= 3:
        osc = slice(free[0], free[-1] + 1)
        s["u_oscillating"] = float(-vy[osc].mean())
        s["u_oscillating_span"] = (float(t[free[0]]), float(t[free[-1]]), float(y[free[0]]), float(y[free[-1]]))
        s["strouhal"] = float(D / (s["lateral_period"] * s["u_oscillating"]))
        last = free[-9:]
        s["u_oscillating_last"] = float(-vy[last[0]:last[-1] + 1].mean())
        s["strouhal_last"] = float(D / (s["lateral_period_last"] * s["u_oscillating_last"]))
        # mean settling speed over successive full periods (three consecutive extremes)
        periods = [(float(t[free[j]]), float(t[free[j + 2]]), float(-vy[free[j]:free[j + 2] + 1].mean()))
                   for j in range(0, free.size - 2, 2)]
        s["u_per_period"] = periods
        if len(periods) >= 2:
            change = periods[-1][2] / periods[-2][2] - 1
            s["u_period_change"] = float(change)
            s["terminal_reached"] = bool(abs(change) < TERMINAL_TOL)
        else:
            s["u_period_change"] = s["terminal_reached"] = None
    else:
        s["u_oscillating"] = s["u_oscillating_span"] = s["strouhal"] = s["strouhal_last"] = None
        s["u_oscillating_last"] = None
        s["u_per_period"], s["u_period_change"], s["terminal_reached"] = [], None, None
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
    p = res["params"]
    height = p.get("height", 6.0)
    if height > 6.0:  # a tall channel: x − 1 against y, stretched across (the disk stays near the centre line)
        ax[2].plot(x - 1.0, y)
        ax[2].axvline(0.0, color="k", lw=0.5)
        ax[2].set_ylim(0, height)
        ax[2].set_xlabel("x − 1 (cm)")
    else:
        ax[2].plot(x, y)
        ax[2].set_xlim(0, 2)
        ax[2].set_ylim(0, height)
        ax[2].set_aspect("equal")
        ax[2].set_xlabel("x (cm)")
    ax[2].set_ylabel("y (cm)")
    ax[2].set_title("trajectory")
    fig.suptitle(f"case {res['case'].upper()}: 2 × {height:g} cm, ρs/ρf = {p['density']:g}, ν = {p['nu']:g} cm²/s, "
                 f"h = {p['h']:g} cm, dt = {p['dt']:g} s, {res['dofs']} DOFs")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def result_name(case: str) -> str:
    """The stem of the result files of ``case`` ("b-tall" → ``sedimentation_case_b_tall``)."""
    return f"sedimentation_case_{case.replace('-', '_')}"


def write(res: dict) -> None:
    name = result_name(res["case"])
    RESULTS.mkdir(exist_ok=True)
    machine = machine_description()
    (RESULTS / f"{name}.json").write_text(json.dumps({"machine": machine, "rows": [res]}, indent=1,
                                                     default=lambda o: o.item()))
    plot(res, RESULTS / f"{name}.png")
    p = res["params"]
    onset = "none" if res["lateral_onset_t"] is None else f"t = {res['lateral_onset_t']:.4f} s"
    extremes = ", ".join(f"({a:.3f}, {b:+.2e})" for a, b in res["lateral_extremes"]) or "none"
    amplitude = "none" if res["lateral_amplitude"] is None else f"{res['lateral_amplitude']:.3g} cm"
    period = (f"{res['lateral_period']:.4g} s" if res.get("lateral_period") is not None else
              f"not measurable (fewer than three extremes more than {FLOOR:g} cm above the floor)")
    u0, u1 = res["u_band"]
    if res["u_terminal_spread"] > 0.01 * res["u_terminal"]:
        trend = "rises" if u1 > u0 else "falls"
        terminal = (f"no terminal state by this measure: −v_y {trend} from {u0:.4f} to {u1:.4f} cm/s across it and "
                    f"spans {res['u_terminal_spread']:.3g} cm/s (mean {res['u_terminal']:.4f})")
    else:
        terminal = (f"terminal speed {res['u_terminal']:.5f} cm/s (mean of −v_y; it varies by "
                    f"{res['u_terminal_spread']:.2g} cm/s across the band)")
    cpu = f", CPU time {res['cpu_s']:.0f} s" if "cpu_s" in res else ""
    dofs = f"{res['dofs_start']} DOFs at the start, {res['dofs']} at the end" if "dofs_start" in res else \
        f"{res['dofs']} DOFs at the end"
    lines = [f"# Sedimentation of one disk, case {res['case'].upper()} (Glowinski et al. 2001; Wan & Turek 2006)", "",
             f"Machine: {machine}; run niced beside other jobs.", "",
             f"Channel 2 × {p.get('height', 6.0):g} cm, closed; disk d = {D} cm ({res['segments']}-gon) released at "
             f"rest at ({1 + p['offset']:g}, {p.get('release', 4.0):g}); ρs/ρf = {p['density']:g}, "
             f"ν = {p['nu']:g} cm²/s, g = {G:g} cm/s²; "
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
    if res.get("settling_history") and p.get("height", 6.0) > 6.0:
        hist = "; ".join(f"{a:.1f} s: {c:.3f} (y {b:.2f})" for a, b, c in res["settling_history"])
        free = res["lateral_extremes_free"]
        lines.append(f"| settling speed −v_y (cm/s) every 0.1 s (height cm) | {hist} |")
        lines.append(f"| extremes more than {FLOOR:g} cm above the floor | {free} |")
        if res.get("lateral_half_periods"):
            lines.append("| half periods between those extremes (s) | "
                         + ", ".join(f"{v:.3f}" for v in res["lateral_half_periods"]) + " |")
        if res.get("lateral_amplitude_last") is not None:
            lines.append(f"| last swing: half peak-to-peak, centre x − 1 | {res['lateral_amplitude_last']:.4g} cm "
                         f"({res['lateral_amplitude_last'] / D:.3g} d), {res['lateral_centre_last']:+.2e} cm |")
        if res.get("strouhal") is not None:
            t0, t1, y0, y1 = res["u_oscillating_span"]
            lines.append(f"| mean settling speed U over the oscillation (t {t0:.3f}–{t1:.3f} s, "
                         f"y {y0:.2f}–{y1:.2f} cm) | {res['u_oscillating']:.4f} cm/s "
                         f"(Re_f = {res['u_oscillating'] * D / p['nu']:.1f}) |")
            last = res["lateral_extremes_free"] and min(9, res["lateral_extremes_free"])
            lines.append(f"| Strouhal number f d / U (f = 1/period) | all extremes above: {res['strouhal']:.4f}; "
                         f"established oscillation (the last {last} extremes, up to four full periods): period "
                         f"{res['lateral_period_last']:.4g} s, U {res['u_oscillating_last']:.4f} cm/s, "
                         f"St {res['strouhal_last']:.4f} |")
            per = "; ".join(f"{a:.3f}–{b:.3f} s: {c:.4f}" for a, b, c in res["u_per_period"])
            lines.append(f"| mean −v_y over successive full periods (cm/s) | {per} |")
        if res.get("terminal_reached") is not None:
            verdict = "yes" if res["terminal_reached"] else "no"
            lines.append(f"| terminal (steady mean) settling speed reached | {verdict}: the last two period means "
                         f"differ by {res['u_period_change']:+.2e} (tolerance {TERMINAL_TOL:g}) |")
        else:
            lines.append("| terminal (steady mean) settling speed reached | not judged (fewer than two full periods "
                         "above the floor) |")
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
    """Recompute the summary of a stored run (``results/sedimentation_case_{case}.json``, "-" in
    ``case`` read as "_") and rewrite its .md and .png."""
    res = json.loads((RESULTS / f"{result_name(case)}.json").read_text())["rows"][0]
    tr = np.array([res["trajectory"][k] for k in ("t", "x", "y", "theta", "vx", "vy", "omega")]).T
    res.update(summary(tr, res["params"]))
    write(res)
    return res


def main(argv) -> None:
    if argv and argv[0] == "report":
        res = report(argv[1])
        print(json.dumps({k: v for k, v in res.items() if k not in ("trajectory", "settling_history")}, indent=1,
                         default=str))
        return
    case = argv[0] if argv else "b"
    max_steps = int(argv[1]) if len(argv) > 1 else None
    res = run(case, max_steps=max_steps)
    if case == "a":
        res["reference"] = reference(res["params"])
    if max_steps is None:
        write(res)
    print(json.dumps({k: v for k, v in res.items() if k not in ("trajectory", "settling_history")}, indent=1,
                     default=str))


if __name__ == "__main__":
    main(sys.argv[1:])
