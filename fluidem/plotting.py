"""Figures of a run directory (matplotlib, PNG): mesh, velocity, pressure, bodies, trajectories, history.

:func:`figures` reads what :class:`fluidem.Simulation` wrote (``fields.pvd``, ``bodies.pvd``,
``history.csv``, ``mesh_quality.csv``, ``scene.toml``) and draws, as matplotlib figures,

* ``mesh``: the fluid mesh at the last output step (fluid scenes),
* ``velocity``: |u| at the last output step with streamlines (fluid scenes),
* ``pressure``: the (dynamic) pressure at the last output step (fluid scenes),
* ``bodies``: the body outlines at the first and last output steps (when a body moves),
* ``trajectories``: the paths of the body centres (when a body moves),
* ``history``: loads, body velocities, body kinetic energy, contacts and mesh quality over
  time: a panel for each that ``history.csv`` and ``mesh_quality.csv`` hold and that is not
  zero throughout;

:func:`plot_run` saves them as ``<name>.png``.  Every axis is labelled with its quantity and
unit and every field figure has a labelled colorbar.  Units are the scene's (one consistent
system, see :mod:`fluidem.scene`): by default written as dimensions (``x [length]``,
``|u| [length/time]``); a scene with ``units = "SI"`` or ``"CGS"`` (or ``units=`` here) names
them (``x [m]``, ``|u| [m/s]``).
In the field figures the bodies are the holes of the fluid mesh of that output step, so
geometry and field are from the same instant.  A box longer than 4:1 is split into up to three
stacked views, or, longer still, cropped to a 4:1 view around the bodies (the title says so).

What the figures read from the run directory, and how they bear a run still writing, is
:mod:`fluidem.figure_inputs`.

matplotlib is needed: ``pip install "fluidem[plot]"`` (:func:`require_matplotlib` says so).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from . import names
from .errors import InputError, install_hint
from .figure_inputs import (PlotWarning, body_outlines, mass_inertia, read_mesh_quality, read_run_history,
                            read_vtu, scene_as_run)
from .io import HISTORY_UNITS, read_pvd
from .io.layout import PathLike

__all__ = ["plot_run", "figures", "require_matplotlib", "view_windows", "UNIT_SYSTEMS", "PlotWarning"]

#: the unit names of each unit system of ``names.choices("units")`` (labels only: nothing is converted)
UNIT_SYSTEMS = {"SI": {"length": "m", "time": "s", "mass": "kg", "force": "N"},
                "CGS": {"length": "cm", "time": "s", "mass": "g", "force": "dyn"}}

#: the most a view may be longer than wide (or taller than long) before it is split or cropped
MAX_ASPECT = 4.0


def require_matplotlib(what: str = "plotting") -> None:
    """Raise :class:`fluidem.errors.InputError` naming ``what`` and the install command if matplotlib is missing.

    ``fluidem run --plot`` calls it before the run, so that a missing matplotlib costs nothing.
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise InputError(f'{what} needs matplotlib: {install_hint("plot")}') from None


def _unit(dim: str, units) -> str:
    """``dim`` (e.g. ``"length/time"``) in the named system, or as it is."""
    if units is None:
        return dim
    names = UNIT_SYSTEMS[units]
    return re.sub(r"(?<![A-Za-z])(length|time|mass|force)(?![A-Za-z])", lambda m: names[m.group(1)], dim)


#: the pressure figure's colour limits: ± this percentile of |p| over the nodes, so that the spikes next
#: to touching bodies (a few nodes) do not wash out the rest of the field
PRESSURE_PERCENTILE = 99.0


def pressure_limit(p: np.ndarray) -> tuple[float, float | None]:
    """Symmetric colour limit of a pressure field ``p`` (n,): ``(lim, max |p|)`` when |p| exceeds ``lim`` =
    the :data:`PRESSURE_PERCENTILE` th percentile of |p| by more than 5 % somewhere (the colours are clipped
    there), else ``(max |p|, None)``.

    >>> p = np.r_[np.linspace(-1.0, 1.0, 999), 50.0]   # one spike
    >>> lim, top = pressure_limit(p)
    >>> round(lim, 2), top
    (0.99, 50.0)
    """
    a = np.abs(np.asarray(p, float))
    a = a[np.isfinite(a)]
    if not len(a):
        return 1.0, None
    top, lim = float(a.max()), float(np.percentile(a, PRESSURE_PERCENTILE))
    if lim <= 0.0:
        return top or 1.0, None
    return (lim, top) if top > 1.05 * lim else (top, None)


def view_windows(box, focus=None, max_aspect: float = MAX_ASPECT) -> tuple[list, bool]:
    """The views ``(x0, x1, y0, y1)`` that show ``box`` readably, and whether they crop it.

    A box at most ``max_aspect`` times longer than wide is one view.  A longer one is split into
    ``n = ceil(aspect / max_aspect)`` equal views along its long side when ``n <= 3``; longer
    still it is cropped to one view of aspect ``max_aspect`` centred on ``focus`` (the bounding
    box ``(x0, x1, y0, y1)`` of the bodies, widened to hold it), or split into at most six
    views when there is no ``focus``.

    Examples
    --------
    >>> view_windows((0, 1, 0, 1))
    ([(0.0, 1.0, 0.0, 1.0)], False)
    >>> view_windows((0, 2.2, 0, 0.41))[0]   # 5.4:1: two stacked halves
    [(0.0, 1.1, 0.0, 0.41), (1.1, 2.2, 0.0, 0.41)]
    >>> view_windows((-24, 24, -1, 1), focus=(-0.2, 0.2, -0.2, 0.2))   # 24:1: cropped around the body
    ([(-4.0, 4.0, -1.0, 1.0)], True)
    """
    x0, x1, y0, y1 = (float(v) for v in box)
    wide = (x1 - x0) >= (y1 - y0)
    if not wide:  # work on the transposed box
        views, crop = view_windows((y0, y1, x0, x1), None if focus is None else
                                   (focus[2], focus[3], focus[0], focus[1]), max_aspect)
        return [(a, b, c, d) for c, d, a, b in views], crop
    L, H = x1 - x0, y1 - y0
    aspect = L / H
    if aspect <= max_aspect * (1 + 1e-9):
        return [(x0, x1, y0, y1)], False
    n = math.ceil(aspect / max_aspect - 1e-9)
    if n <= 3 or focus is None:
        n = min(n, 6)
        edges = np.linspace(x0, x1, n + 1)
        return [(float(a), float(b), y0, y1) for a, b in zip(edges[:-1], edges[1:])], False
    w = min(max(max_aspect * H, (focus[1] - focus[0]) + H), L)
    c = 0.5 * (focus[0] + focus[1])
    a = min(max(c - 0.5 * w, x0), x1 - w)
    return [(float(a), float(a + w), y0, y1)], True


def _holes(points: np.ndarray, tri: np.ndarray) -> tuple[list, np.ndarray]:
    """The holes of a triangulation (its boundary loops but the outer one) and every boundary edge.

    Returns ``(loops, edges)``: ``loops`` a list of (n_i, 2) vertex arrays, ``edges`` (m, 2, 2)
    the boundary edges' end points (for drawing outlines that touch the outer boundary too).
    """
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    _, inv, cnt = np.unique(np.sort(e, axis=1), axis=0, return_inverse=True, return_counts=True)
    b = e[cnt[inv.ravel()] == 1]
    nxt = dict(zip(b[:, 0].tolist(), b[:, 1].tolist()))
    loops, seen = [], set()
    for start in nxt:  # boundary loops: small, once per figure
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen and v in nxt:
            seen.add(v)
            loop.append(v)
            v = nxt[v]
        if len(loop) >= 3:
            loops.append(points[loop])
    if loops:
        areas = [abs(_area(p)) for p in loops]
        loops.pop(int(np.argmax(areas)))  # the outer boundary
    return loops, points[b]


def _area(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))



def figures(out_dir: PathLike, units: str | None = None) -> dict:
    """The figures of a run directory, as matplotlib figures (not saved; :func:`plot_run` saves them).

    Parameters
    ----------
    out_dir : str or Path
        Directory written by :meth:`fluidem.Simulation.run`.
    units : {None, "SI", "CGS"}
        How the axis labels name units: in that system (``[m]``), or ``None``: the scene's
        ``units`` if it names them, else by dimension (``[length]``); nothing is converted.

    Returns
    -------
    dict
        name -> :class:`matplotlib.figure.Figure`, in the order of the module docstring; only
        the figures the run has data for (no fluid figures in a dry scene, no bodies or
        trajectories when no body moves).

    Raises
    ------
    fluidem.errors.InputError
        ``out_dir`` holds no ``history.csv``, ``units`` is not a known system, or matplotlib
        is missing.
    """
    require_matplotlib("plotting")
    if units is not None:
        units = names.lookup("units", units, "units")
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    if not (out_dir / "history.csv").exists():
        raise InputError(f"out_dir = {str(out_dir)!r} is not a fluidem run directory: expected a directory written "
                         "by 'fluidem run' (with a history.csv)")
    scene = scene_as_run(out_dir)
    if units is None and scene is not None:
        units = scene.units
    u = lambda dim: _unit(dim, units)  # noqa: E731
    h = read_run_history(out_dir)
    bodies_series = read_pvd(out_dir / "bodies.pvd") if (out_dir / "bodies.pvd").exists() else []
    fields = read_pvd(out_dir / "fields.pvd") if (out_dir / "fields.pvd").exists() else []
    box = scene.domain.box if scene is not None else None
    if box is None and fields:
        p = read_vtu(fields[-1][1]).points
        box = (p[:, 0].min(), p[:, 0].max(), p[:, 1].min(), p[:, 1].max())
    focus = None
    if len(h["t"]):
        focus = (h["x"].min(), h["x"].max(), h["y"].min(), h["y"].max())
        if scene is not None and scene.bodies:
            r = max(b.bounding_radius for b in scene.bodies)
            focus = (focus[0] - r, focus[1] + r, focus[2] - r, focus[3] + r)
    if box is None:
        box = focus if focus is not None else (0.0, 1.0, 0.0, 1.0)
    canvas = _Canvas(plt, box, focus, u)
    figs = {}
    if fields:
        figs.update(_field_figures(canvas, fields, h))
    figs.update(_body_figures(canvas, h, bodies_series))
    hist = _history_figure(plt, h, mass_inertia(scene), read_mesh_quality(out_dir), scene, u)
    if hist is not None:
        figs["history"] = hist
    return figs


class _Canvas:
    """The views of a run's box (:func:`view_windows`) and how its figures are drawn: labelled, equal-aspect
    planes, body outlines, the holes of a field mesh."""

    def __init__(self, plt, box, focus, u):
        self.plt, self.box, self.u = plt, box, u
        self.views, self.cropped = view_windows(box, focus)

    def plane(self, title, colorbar=None):
        """A figure with one axes per view, labelled, equal aspect."""
        views, box, u = self.views, self.box, self.u
        vw, vh = views[0][1] - views[0][0], views[0][3] - views[0][2]
        stacked = vw >= vh
        n = len(views)
        width = 9.0
        panel_h = max(1.6, min(7.0, width * vh / vw)) if stacked else max(2.5, min(7.0, width / n * vh / vw))
        size = (width + (1.4 if colorbar else 0), (panel_h * n if stacked else panel_h) + 0.8)
        fig, axes = self.plt.subplots(n if stacked else 1, 1 if stacked else n, squeeze=False, figsize=size)
        axes = list(axes.ravel())
        for ax, (a, b, c, d) in zip(axes, views):
            ax.set_xlim(a, b)
            ax.set_ylim(c, d)
            ax.set_aspect("equal")
            ax.set_xlabel(f"x [{u('length')}]")
            ax.set_ylabel(f"y [{u('length')}]")
        if self.cropped:
            title += f" (view x = {views[0][0]:.3g}..{views[0][1]:.3g}, y = {views[0][2]:.3g}..{views[0][3]:.3g} " \
                     f"of the box {box[0]:.3g}..{box[1]:.3g} × {box[2]:.3g}..{box[3]:.3g})"
        axes[0].set_title(title, fontsize=10)
        return fig, axes

    @staticmethod
    def outlines(ax, outlines, **kw):
        from matplotlib.collections import PolyCollection

        if outlines:
            ax.add_collection(PolyCollection(outlines, **{"facecolor": "0.6", "edgecolor": "k", "linewidth": 0.5,
                                                          **kw}))

    def holes(self, ax, holes, edges):
        from matplotlib.collections import LineCollection

        self.outlines(ax, holes, linewidth=0.0)
        if len(edges):
            ax.add_collection(LineCollection(edges, colors="k", linewidths=0.6))


def _field_figures(canvas: _Canvas, fields: list, h: dict) -> dict:
    """Mesh, velocity and pressure of the last fields written (their time, and the run's if it went on)."""
    import matplotlib.tri as mtri

    u, box = canvas.u, canvas.box
    t_f, f_last = fields[-1]
    t_run = float(h["t"].max()) if len(h["t"]) else t_f
    # the fields are written every output.every steps: say when the run went on past the last of them
    when = f"t = {t_f:.4g}" + (f" (last fields written; the run reached t = {t_run:.4g})"
                               if t_run > t_f + 1e-9 * max(abs(t_run), 1.0) else "")
    m = read_vtu(f_last)
    pts, tri = m.points[:, :2], m.cells_dict["triangle"]
    T = mtri.Triangulation(pts[:, 0], pts[:, 1], tri)
    holes, edges = _holes(pts, tri)
    x0, x1, y0, y1 = box
    tol = 1e-9 * max(x1 - x0, y1 - y0)
    on_box = lambda q: (np.abs(q[..., 0] - x0) < tol) | (np.abs(q[..., 0] - x1) < tol) | \
        (np.abs(q[..., 1] - y0) < tol) | (np.abs(q[..., 1] - y1) < tol)  # noqa: E731
    body_edges = edges[~(on_box(edges[:, 0]) & on_box(edges[:, 1]))] if len(edges) else edges
    figs = {}

    fig, axes = canvas.plane(f"mesh at {when}: {len(pts)} vertices, {len(tri)} triangles")
    for ax in axes:
        ax.triplot(T, color="0.3", linewidth=0.2)
        canvas.holes(ax, holes, body_edges)
    figs["mesh"] = fig

    vel = m.point_data["velocity"]
    speed = np.hypot(vel[:, 0], vel[:, 1])
    fig, axes = canvas.plane(f"velocity magnitude and streamlines, {when}", colorbar=True)
    ui, vi = mtri.LinearTriInterpolator(T, vel[:, 0]), mtri.LinearTriInterpolator(T, vel[:, 1])
    for ax, (a, b, c, d) in zip(axes, canvas.views):
        tc = ax.tripcolor(T, speed, shading="gouraud", cmap="viridis", vmin=0.0, vmax=float(speed.max()) or 1.0)
        nx = 160
        ny = max(16, int(nx * (d - c) / (b - a)))
        X, Y = np.meshgrid(np.linspace(a, b, nx), np.linspace(c, d, ny))
        U, V = ui(X, Y), vi(X, Y)
        if np.ma.count(U) > 4 and float(np.ma.max(np.hypot(U, V))) > 0:
            ax.streamplot(X, Y, U.filled(np.nan), V.filled(np.nan), color="w", linewidth=0.5, density=1.0,
                          arrowsize=0.6)
        canvas.holes(ax, holes, body_edges)
    fig.colorbar(tc, ax=axes, label=f"|u| [{u('length/time')}]", shrink=0.9)
    figs["velocity"] = fig

    p = m.point_data["pressure"]
    lim, clipped = pressure_limit(p)
    fig, axes = canvas.plane(f"pressure (dynamic), {when}" + (
        f"; colours clipped at ±{lim:.3g}, the {PRESSURE_PERCENTILE:g}th percentile of |p| (max {clipped:.3g})"
        if clipped else ""), colorbar=True)
    for ax in axes:
        tc = ax.tripcolor(T, p, shading="gouraud", cmap="RdBu_r", vmin=-lim, vmax=lim)
        canvas.holes(ax, holes, body_edges)
    fig.colorbar(tc, ax=axes, label=f"p [{u('force/length²')}]", shrink=0.9)
    figs["pressure"] = fig
    return figs


def _body_figures(canvas: _Canvas, h: dict, bodies_series: list) -> dict:
    """The bodies at the first and last output and the trajectories of their centres, when any moves."""
    box = canvas.box
    ids = np.unique(h["id"])
    span = max(box[1] - box[0], box[3] - box[2])
    moving = any(np.ptp(h["x"][h["id"] == k]) > 1e-12 * span or np.ptp(h["y"][h["id"] == k]) > 1e-12 * span
                 for k in ids) if len(h["t"]) else False
    if not moving:
        return {}
    figs = {}
    last = body_outlines(bodies_series[-1][1]) if bodies_series else []
    if bodies_series:
        fig, axes = canvas.plane(f"bodies at t = {bodies_series[0][0]:.4g} (dashed) and t = {bodies_series[-1][0]:.4g}")
        first = body_outlines(bodies_series[0][1])
        for ax in axes:
            canvas.outlines(ax, first, facecolor="none", edgecolor="0.5", linestyle="--")
            canvas.outlines(ax, last, facecolor="tab:orange", alpha=0.8)
        figs["bodies"] = fig
    figs["trajectories"] = _trajectory_figure(canvas, h, ids, last)
    return figs


def _trajectory_figure(canvas: _Canvas, h: dict, ids: np.ndarray, last: list):
    """Body centres' paths coloured by time on one scale, starts (o) and ends (■) marked."""
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize

    t0, t1 = float(h["t"].min()), float(h["t"].max())
    fig, axes = canvas.plane(f"trajectories of {len(ids)} body centres coloured by time, t = {t0:.4g}..{t1:.4g} "
                             "(o start, ■ end)", colorbar=True)
    norm = Normalize(t0, t1 if t1 > t0 else t0 + 1.0)
    segs, times, starts, ends = [], [], [], []
    for k in ids[:: max(1, len(ids) // 200)]:  # at most ~200 paths drawn
        sel = h["id"] == k
        xy = np.column_stack([h["x"][sel], h["y"][sel]])
        seg = np.stack([xy[:-1], xy[1:]], axis=1)
        tm = 0.5 * (h["t"][sel][:-1] + h["t"][sel][1:])
        if "x_unwrapped" in h:  # no segment across the box where a body crossed a periodic side
            uw = np.column_stack([h["x_unwrapped"][sel], h["y_unwrapped"][sel]])
            same = (np.abs(np.diff(uw, axis=0) - np.diff(xy, axis=0)) <= 1e-9 * (1.0 + np.abs(uw[1:]))).all(axis=1)
            seg, tm = seg[same], tm[same]
        segs.append(seg)
        times.append(tm)
        starts.append(xy[0])
        ends.append(xy[-1])
    for ax in axes:
        lc = LineCollection(np.concatenate(segs), cmap="viridis", norm=norm, linewidths=0.8 if len(ids) > 50 else 1.4)
        lc.set_array(np.concatenate(times))
        ax.add_collection(lc)
        ax.plot(*np.array(starts).T, "o", ms=2.5, mfc="none", mec="0.2", mew=0.6)
        ax.plot(*np.array(ends).T, "s", ms=2.5, color="k")
        canvas.outlines(ax, last, facecolor="none", edgecolor="k", linewidth=0.3)
    fig.colorbar(lc, ax=axes, label=f"t [{canvas.u('time')}]", shrink=0.9)
    return fig


def _history_figure(plt, h, mass, quality, scene, u):
    """Loads, velocities, kinetic energy, contacts and mesh quality over time: one panel each that is not all zero."""
    if not len(h["t"]) and quality is None:
        return None
    steps, inv = np.unique(h["step"], return_inverse=True)
    t = np.zeros(len(steps))
    t[inv] = h["t"]
    ids = np.unique(h["id"])
    few = len(ids) <= 8
    fluid = scene is not None and scene.fluid is not None
    panels = []  # (ylabel, [(label, t, y)])

    def per_body(col):
        return [(f"{col}, body {k}", h["t"][h["id"] == k], h[col][h["id"] == k]) for k in ids]

    def total(col):
        return np.bincount(inv, weights=h[col], minlength=len(steps))

    if len(h["t"]):
        load = "hydrodynamic load" if fluid else "contact load"
        if np.any(h["fx"]) or np.any(h["fy"]):
            lines = per_body("fx") + per_body("fy") if few else \
                [("Σ fx", t, total("fx")), ("Σ fy", t, total("fy"))]
            panels.append((f"{load} [{u(HISTORY_UNITS['fx'])}]", lines))
        if np.any(h["torque"]):
            lines = per_body("torque") if few else [("Σ torque", t, total("torque"))]
            panels.append((f"torque [{u(HISTORY_UNITS['torque'])}]", lines))
        if np.any(h["vx"]) or np.any(h["vy"]):
            if few:
                lines = per_body("vx") + per_body("vy")
            else:
                sp = np.hypot(h["vx"], h["vy"])
                mx = np.zeros(len(steps))
                np.maximum.at(mx, inv, sp)
                lines = [("mean |v|", t, np.bincount(inv, weights=sp, minlength=len(steps))
                          / np.bincount(inv, minlength=len(steps))), ("max |v|", t, mx)]
            panels.append((f"body velocity [{u(HISTORY_UNITS['vx'])}]", lines))
        if np.any(h["omega"]):
            lines = per_body("omega") if few else [("max |ω|", t, _max_by(inv, np.abs(h["omega"]), len(steps)))]
            panels.append((f"angular velocity [{u(HISTORY_UNITS['omega'])}]", lines))
        if mass is not None and (np.any(h["vx"]) or np.any(h["vy"]) or np.any(h["omega"])) \
                and len(mass[0]) > int(h["id"].max()):
            m, J = mass[0][h["id"]], mass[1][h["id"]]
            ke = np.bincount(inv, weights=0.5 * m * (h["vx"] ** 2 + h["vy"] ** 2), minlength=len(steps))
            kr = np.bincount(inv, weights=0.5 * J * h["omega"] ** 2, minlength=len(steps))
            lines = [("translation", t, ke)] + ([("rotation", t, kr)] if np.any(kr) else [])
            panels.append((f"body kinetic energy [{u('mass·length²/time²')}]", lines))
        if np.any(h["contacts"]):
            panels.append(("contacts [1]", [("contacts, summed over the bodies", t, total("contacts"))]))
    if quality is not None and len(quality["t"]) > 1:  # a mesh built once has one row: nothing over time
        panels.append(("mesh angles [deg]", [("min angle", quality["t"], quality["min_angle"]),
                                             ("max angle", quality["t"], quality["max_angle"])]))
    if not panels:
        return None
    fig, axes = plt.subplots(len(panels), 1, sharex=True, squeeze=False, figsize=(8, 2.1 * len(panels) + 0.6))
    axes = axes[:, 0]
    for ax, (ylabel, lines) in zip(axes, panels):
        for label, x, y in lines:
            ax.plot(x, y, marker="." if len(x) < 30 else None, label=label)
        ax.set_ylabel(ylabel, fontsize=9)
        ax.grid(True, linewidth=0.3)
        if len(lines) <= 8:  # which body, or which sum or maximum over the bodies
            ax.legend(fontsize=7, loc="best")
    axes[-1].set_xlabel(f"t [{u('time')}]")
    axes[0].set_title("history" + (f" of {len(ids)} bod{'y' if len(ids) == 1 else 'ies'}" if len(ids) else ""),
                      fontsize=10)
    fig.tight_layout()
    return fig


def _max_by(inv, values, n):
    out = np.zeros(n)
    np.maximum.at(out, inv, values)
    return out


def plot_run(out_dir: PathLike, save_dir: PathLike | None = None, dpi: int = 120, units: str | None = None) -> list:
    """Draw the figures of a run directory (:func:`figures`) to PNG files.

    Parameters
    ----------
    out_dir : str or Path
        Directory written by :meth:`fluidem.Simulation.run`.
    save_dir : str or Path, optional
        Where to put the PNG files (default: ``out_dir/plots``).
    dpi : int
        Resolution of the PNG files, dots per inch.
    units : {None, "SI", "CGS"}
        Unit names in the labels (see :func:`figures`).

    Returns
    -------
    list of Path
        The files written, ``<name>.png`` for each figure.

    Raises
    ------
    fluidem.errors.InputError
        ``out_dir`` holds no ``history.csv`` (also a ``ValueError``), or matplotlib is missing.

    Examples
    --------
    >>> import tempfile
    >>> import fluidem
    >>> from fluidem.plotting import plot_run
    >>> s = fluidem.Scene.from_dict({"gravity": [0, -10], "domain": {"box": [0, 1, 0, 1]},
    ...     "bodies": [{"shape": "disk", "radius": 0.05, "position": [0.5, 0.8]}],
    ...     "time": {"dt": 0.01, "t_end": 0.1}})
    >>> d = tempfile.mkdtemp()
    >>> _ = fluidem.Simulation(s).run(out_dir=d)
    >>> sorted(p.name for p in plot_run(d))   # a dry scene: no mesh, velocity or pressure
    ['bodies.png', 'history.png', 'trajectories.png']
    """
    import matplotlib.pyplot as plt

    figs = figures(out_dir, units=units)
    save = Path(save_dir) if save_dir is not None else Path(out_dir) / "plots"
    save.mkdir(parents=True, exist_ok=True)
    written = []
    for name, fig in figs.items():
        path = save / f"{name}.png"
        fig.savefig(path, dpi=dpi, bbox_inches="tight")
        plt.close(fig)
        written.append(path)
    return written
