"""The DKT accuracy variant (Uhlmann 2005, Sec. 5.2) against two published methods' trajectories.

Set-up :func:`fluidem.cases.dkt.uhlmann_dkt_scene` (CGS): disks d = 0.25 cm (regular 96-gons),
ρ_s/ρ_f = 1.5, ν = 0.01 cm²/s, g = 981 cm/s², closed channel 2 × 6 cm (8d × 24d), centres 4d
(trailing) and 6d (leading) below the top wall, lateral offsets +d/250 and −d/250; P2+bubble/P1dc,
mesh size h at the disks graded ×1.2 to 8h, implicit coupling, the default contact model (lubrication
correction below h, repulsion backstop below 0.01 h);
dt = h / 20 s (a CFL number of about 1 at the largest speed, 19 cm/s); to t = 0.3 s (16.7 t_ref),
the end of the published curves.  u_ref = √(π d (ρ_s/ρ_f − 1) g/2) = 13.88 cm/s, t_ref = d/u_ref
= 0.0180 s, Re_ref = 347 (the peak fall speed gives U d/ν ≈ 475).

References (``benchmarks/reference/dkt_uhlmann/``, digitised curves, see SOURCE.md there): Uhlmann
(2005, immersed boundary) Figs. 6a/6b/7a and Koblitz et al. (2017, body-conforming overset grids)
Fig. 10a/c/d.  Compared: the fall distance from the top wall and the lateral position of each disk
(our series interpolated at the digitised times), before kissing (t < the reference's kissing time)
and over the whole run, in units of d; the kissing time, defined for all three as the first time the
centres are closer than 1.1 d.  The difference between the two references themselves is given
beside it: it is what "agreement" can mean here.

Writes ``benchmarks/results/dkt_uhlmann.{md,json,png}`` (rewritten after every run).

Run (about 30 minutes on one core for the three resolutions)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dkt_uhlmann.py [h ...]     # run (default all), write;
                                                                              # stored runs at other h are kept
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dkt_uhlmann.py report      # redraw from the JSON
"""

from __future__ import annotations

import json
import os
import pathlib
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.dkt import UHLMANN, uhlmann_dkt_scene  # noqa: E402
from fluidem.simulation import Simulation  # noqa: E402

REFERENCE = pathlib.Path(__file__).parent / "reference" / "dkt_uhlmann"
D, W, H = UHLMANN["d"], UHLMANN["width"], UHLMANN["height"]
T_REF, U_REF = UHLMANN["t_ref"], UHLMANN["u_ref"]
KISS_DISTANCE = 1.1  # centres closer than 1.1 d: "kissing", for every series alike
RESOLUTIONS = (0.02, 0.015, 0.01)
COLUMNS = ("t", "fall_lead", "lat_lead", "fall_trail", "lat_trail", "vfall_lead", "vfall_trail", "gap", "wall_s")


def _curve(name):
    a = np.loadtxt(REFERENCE / name)
    return a[np.argsort(a[:, 0], kind="stable")]


def references() -> dict:
    """The digitised curves in this benchmark's units: t (s); fall distance from the top, lateral
    position from the centre line (cm); fall speed (cm/s, positive down).  Per source and disk a
    dict of (n, 2) arrays ``fall``, ``lateral``, ``vfall``."""
    out = {}
    for disk in ("leading", "trailing"):
        u = out.setdefault("Uhlmann 2005", {})[disk] = {}
        u["fall"] = _curve(f"Uhlmann2005-fig6a-{disk}-particle.csv")
        u["lateral"] = _curve(f"Uhlmann2005-fig7a-{disk}-particle.csv")
        u["vfall"] = _curve(f"Uhlmann2005-fig6b-{disk}-particle.csv")
        k = out.setdefault("Koblitz et al. 2017", {})[disk] = {}
        c = _curve(f"Koblitz2017-fig10c-{disk}-particle.csv")
        k["fall"] = np.column_stack([c[:, 0] * T_REF, -c[:, 1] * D])
        c = _curve(f"Koblitz2017-fig10a-{disk}-particle.csv")
        k["lateral"] = np.column_stack([c[:, 0] * T_REF, (c[:, 1] - 4.0) * D])
        c = _curve(f"Koblitz2017-fig10d-{disk}-particle.csv")
        k["vfall"] = np.column_stack([c[:, 0] * T_REF, -c[:, 1] * U_REF])
    return out


def _keep_t(a, t0, t1):
    return a[(a[:, 0] >= t0) & (a[:, 0] <= t1)]


def kissing_time(t, fall_lead, lat_lead, fall_trail, lat_trail) -> float:
    """First time the centres are closer than ``KISS_DISTANCE`` d (NaN if never)."""
    dist = np.hypot(fall_lead - fall_trail, lat_lead - lat_trail)
    k = np.flatnonzero(dist < KISS_DISTANCE * D)
    return float(t[k[0]]) if len(k) else float("nan")


def reference_kiss(ref: dict) -> float:
    """Kissing time of a digitised reference (both disks' curves on one time grid)."""
    lo = max(ref[d][q][0, 0] for d in ref for q in ("fall", "lateral"))
    hi = min(ref[d][q][-1, 0] for d in ref for q in ("fall", "lateral"))
    t = np.linspace(max(lo, 0.0), hi, 3001)
    f = {(d, q): np.interp(t, *ref[d][q].T) for d in ref for q in ("fall", "lateral")}
    return kissing_time(t, f["leading", "fall"], f["leading", "lateral"], f["trailing", "fall"],
                        f["trailing", "lateral"])


def deviations(t, series: dict, ref: dict, t_end: float, lateral_sign: float = 1.0) -> dict:
    """Largest |ours − reference| / d at the reference's digitised times ≤ ``t_end``, per disk and
    coordinate; ``series[(disk, q)]`` our values at times ``t``."""
    out = {}
    for disk in ("leading", "trailing"):
        for q in ("fall", "lateral"):
            r = _keep_t(ref[disk][q], t[0], min(t_end, t[-1]))
            sign = lateral_sign if q == "lateral" else 1.0
            out[f"{q}_{disk}"] = float(np.abs(sign * np.interp(r[:, 0], t, series[disk, q]) - r[:, 1]).max() / D) \
                if len(r) else float("nan")
    return out


def compare(rec: dict) -> dict:
    """Kissing times and deviations of one run against both references (and of the references
    from each other), the lateral sign that matches the references stated."""
    R = np.array(rec["rows"])
    t = R[:, 0]
    series = {("leading", "fall"): R[:, 1], ("leading", "lateral"): R[:, 2],
              ("trailing", "fall"): R[:, 3], ("trailing", "lateral"): R[:, 4]}
    refs = references()
    out = {"t_kiss": kissing_time(t, R[:, 1], R[:, 2], R[:, 3], R[:, 4]), "against": {}}
    for name, ref in refs.items():
        tk = reference_kiss(ref)
        devs = {s: deviations(t, series, ref, t[-1], s) for s in (1.0, -1.0)}
        sign = min(devs, key=lambda s: sum(devs[s][f"lateral_{d}"] for d in ("leading", "trailing")))
        out["against"][name] = {"t_kiss": tk, "lateral_sign": sign,
                                "before_kiss": deviations(t, series, ref, tk, sign), "whole": devs[sign]}
    # the two references against each other (Koblitz interpolated at Uhlmann's digitised times)
    (na, a), (nb, b) = refs.items()
    grid = np.linspace(0.0, 0.3, 601)
    s_b = {(d, q): np.interp(grid, *b[d][q].T) for d in b for q in ("fall", "lateral")}
    out["references"] = {"pair": f"{nb} at the times of {na}",
                         "before_kiss": deviations(grid, s_b, a, reference_kiss(a)),
                         "whole": deviations(grid, s_b, a, 0.3)}
    return out


def run(h: float, t_end: float = 0.3, log=sys.stderr) -> dict:
    """One run at mesh size ``h`` (cm), dt = h/20; returns the record (rows of :data:`COLUMNS`)."""
    dt = h / 20
    t0 = time.perf_counter()
    c0 = time.process_time()
    sim = Simulation(uhlmann_dkt_scene(h=h, dt=dt, t_end=t_end))
    fl = sim.flow
    rows, parts = [], {}

    def step(k, n, t, cost):
        P, V = fl.poses, fl.body_velocities
        gap = float(np.hypot(*(P[1, :2] - P[0, :2])) - D)
        rows.append([fl.t, H - P[0, 1], P[0, 0] - W / 2, H - P[1, 1], P[1, 0] - W / 2, -V[0, 1], -V[1, 1], gap,
                     time.perf_counter() - t0])
        for name, s in cost.parts.items():
            parts[name] = parts.get(name, 0.0) + s
        if log is not None and k % 50 == 0:
            print(f"h {h} step {k}/{n} t = {t:.4f} gap {gap:.4f} {rows[-1][-1]:.0f} s", file=log, flush=True)

    sim.run(out_dir=None, progress=step)
    rec = {"h": h, "dt": dt, "t_end": t_end, "dofs": int(fl.dofs), "steps": len(rows),
           "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
           "cost_per_step_s": {k: v / max(len(rows), 1) for k, v in parts.items()},
           "triangulations": int(sim.counters["triangulations"]), "contact_substeps": int(fl.contacts.substeps),
           "min_gap": float(min(r[7] for r in rows)), "repulsion_range": float(fl.contacts.repulsion.range),
           "load_average": os.getloadavg()[0], "dem_force_velocity": DEM_FORCE_VELOCITY, "rows": rows}
    rec["comparison"] = compare(rec)
    return rec


#: The velocity the DEM's contact forces see (:mod:`fluidem.dem.system`, "Velocity"), stored with each
#: run: rows without it were measured when the forces saw the predictor velocity v_n + a_n dt.
DEM_FORCE_VELOCITY = "mid-step"


def merged(new: list) -> list:
    """The stored runs with those of ``new`` replaced (same h) or added, finest last."""
    path = RESULTS / "dkt_uhlmann.json"
    old = json.loads(path.read_text())["rows"] if path.exists() else []
    hs = {r["h"] for r in new}
    return sorted([r for r in old if r["h"] not in hs] + new, key=lambda r: -r["h"])


def report(recs: list, machine: str) -> None:
    """Markdown and figure from the stored records."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    refs = references()
    lines = ["# DKT accuracy variant (Uhlmann 2005): two disks, ρ_s/ρ_f = 1.5, Re_ref = 347", "",
             f"Machine: {machine}; one BLAS thread.", "",
             "Deviations: largest |fluidem − reference| over the digitised points, in units of d = 0.25 cm, "
             f"for t before the reference's kissing time (centres closer than {KISS_DISTANCE} d) and over the whole "
             "run (to t = 0.3 s).  'fall' is the distance from the top wall, 'lat' the lateral position.", "",
             "| h cm | dt s | DOFs | steps | wall s | CPU s | s/step | re-triangulations | t_kiss s (t/t_ref) | "
             "min gap cm (centres − d) | reference | ref t_kiss s | lat sign | "
             "before kiss: fall lead / trail, lat lead / trail | whole run: fall lead / trail, lat lead / trail |",
             "|" + "---|" * 15]

    def four(d):
        return " / ".join(f"{d[f'{q}_{s}']:.3f}" for q in ("fall", "lateral") for s in ("leading", "trailing"))

    for r in recs:
        c = r["comparison"]
        for k, (name, a) in enumerate(c["against"].items()):
            head = (f"| {r['h']} | {r['dt']:.2g} | {r['dofs']} | {r['steps']} | {r['wall_s']:.0f} | {r['cpu_s']:.0f} | "
                    f"{r['wall_s'] / max(r['steps'], 1):.2f} | {r['triangulations']} | {c['t_kiss']:.4f} "
                    f"({c['t_kiss'] / T_REF:.2f}) | {r['min_gap']:.1e} |") if k == 0 else "| | | | | | | | | | |"
            lines.append(f"{head} {name} | {a['t_kiss']:.4f} ({a['t_kiss'] / T_REF:.2f}) | {a['lateral_sign']:+.0f} | "
                         f"{four(a['before_kiss'])} | {four(a['whole'])} |")
    stale = [r["h"] for r in recs if r.get("dem_force_velocity") != DEM_FORCE_VELOCITY]
    if stale:
        lines += ["", f"Runs at h = {', '.join(map(str, stale))} are from an earlier version whose DEM forces saw "
                      "the predictor velocity v_n + a_n dt instead of the mid-step velocity (not re-run since)."]
    if recs:
        c = recs[0]["comparison"]["references"]
        lines += ["", f"The references against each other ({c['pair']}): before kiss {four(c['before_kiss'])}, "
                      f"whole run {four(c['whole'])} (fall lead / trail, lat lead / trail, in d)."]
        split = ", ".join(f"{k} {v:.3f}" for k, v in recs[-1]["cost_per_step_s"].items() if v > 0)
        lines += ["", f"Cost per step (s) of the finest run: {split}."]
    (RESULTS / "dkt_uhlmann.md").write_text("\n".join(lines) + "\n")

    fig, ax = plt.subplots(1, 3, figsize=(13, 4.2))
    styles = {"Uhlmann 2005": dict(ls="none", marker="o", ms=3, mfc="none"), "Koblitz et al. 2017": dict(ls="--", lw=1)}
    for name, ref in refs.items():
        for disk, col in (("leading", "C0"), ("trailing", "C3")):
            for k, q in enumerate(("fall", "lateral", "vfall")):
                a = ref[disk][q]
                scale = 1.0 if q == "vfall" else 1.0 / D
                ax[k].plot(a[:, 0] / T_REF, a[:, 1] * scale, color=col, label=f"{name} {disk}", **styles[name])
    for r in recs:
        R = np.array(r["rows"])
        sign = r["comparison"]["against"]["Uhlmann 2005"]["lateral_sign"]
        lw = 0.8 + 1.2 * (r["h"] == min(x["h"] for x in recs))
        for disk, col, j in (("leading", "C0", 1), ("trailing", "C3", 3)):
            ax[0].plot(R[:, 0] / T_REF, R[:, j] / D, color=col, lw=lw, alpha=0.85, label=f"fluidem h {r['h']} {disk}")
            ax[1].plot(R[:, 0] / T_REF, sign * R[:, j + 1] / D, color=col, lw=lw, alpha=0.85)
            ax[2].plot(R[:, 0] / T_REF, R[:, 5 + (j == 3)], color=col, lw=lw, alpha=0.85)
    ax[0].set(xlabel="t / t_ref", ylabel="fall distance from the top / d", title="fall")
    ax[1].set(xlabel="t / t_ref", ylabel="lateral position / d", title="lateral (sign as the references)")
    ax[2].set(xlabel="t / t_ref", ylabel="fall speed [cm/s]", title="fall speed")
    ax[0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(RESULTS / "dkt_uhlmann.png", dpi=110)


if __name__ == "__main__":
    if sys.argv[1:] == ["report"]:
        data = json.loads((RESULTS / "dkt_uhlmann.json").read_text())
        for r in data["rows"]:
            r["comparison"] = compare(r)
        report(data["rows"], data["machine"])
    else:
        hs = [float(a) for a in sys.argv[1:]] or list(RESOLUTIONS)
        new = []
        for h in hs:  # the other resolutions' stored runs are kept
            new.append(run(h))
            machine = machine_description()
            recs = merged(new)
            for r in recs:  # stored runs carry theirs
                if "comparison" not in r:
                    r["comparison"] = compare(r)
            write_json("dkt_uhlmann", machine, recs)
            report(recs, machine)
