"""Figures of a run directory (matplotlib, PNG): mesh with bodies, velocity, pressure, trajectories.

:func:`plot_run` reads what :class:`fluidem.Simulation` wrote (``fields.pvd``,
``bodies.pvd``, ``history.csv``) and draws

* ``mesh.png``: the fluid mesh with the body outlines (fluid scenes),
* ``velocity.png``: |u| at the last output step with streamlines (fluid scenes),
* ``pressure.png``: the pressure at the last output step (fluid scenes),
* ``bodies.png``: the body outlines at the first and last output steps (all scenes),
* ``trajectories.png``: the paths of the body centres from ``history.csv``.

matplotlib is needed (it is in the ``test`` extra, not a dependency of fluidem).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import InputError
from .io import PathLike, read_history, read_pvd

__all__ = ["plot_run", "require_matplotlib"]


def require_matplotlib(what: str = "plotting") -> None:
    """Raise :class:`fluidem.errors.InputError` naming ``what`` and the install command if matplotlib is missing.

    ``fluidem run --plot`` calls it before the run, so that a missing matplotlib costs nothing.
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise InputError(f'{what} needs matplotlib: pip install "fluidem[plot]"') from None


def _outlines(vtu):
    import meshio

    m = meshio.read(vtu)
    out = []
    for block in m.cells:
        for conn in block.data:
            out.append(m.points[conn, :2])
    return out


def _draw_bodies(ax, outlines, **kw):
    from matplotlib.collections import PolyCollection

    if outlines:
        ax.add_collection(PolyCollection(outlines, **{"facecolor": "0.6", "edgecolor": "k", "linewidth": 0.5, **kw}))


def _box(out_dir: Path) -> tuple | None:
    try:  # the scene as run gives the box
        from .scene import Scene

        return Scene.from_toml(out_dir / "scene.toml").domain.box
    except (ValueError, OSError):
        return None


def plot_run(out_dir: PathLike, save_dir: PathLike | None = None, dpi: int = 120) -> list[Path]:
    """Draw the figures of a run directory to PNG files.

    Parameters
    ----------
    out_dir : str or Path
        Directory written by :meth:`fluidem.Simulation.run`.
    save_dir : str or Path, optional
        Where to put the PNG files (default: ``out_dir/plots``).
    dpi : int
        Resolution of the PNG files, dots per inch.

    Returns
    -------
    list of Path
        The files written (the fluid figures only for a fluid scene).

    Raises
    ------
    fluidem.errors.InputError
        ``out_dir`` holds no ``history.csv`` (also a ``ValueError``).

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
    ['bodies.png', 'trajectories.png']
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    import matplotlib.tri as mtri
    import meshio

    out_dir = Path(out_dir)
    if not (out_dir / "history.csv").exists():
        raise InputError(f"out_dir = {str(out_dir)!r} is not a fluidem run directory: expected a directory written "
                         "by 'fluidem run' (with a history.csv)")
    save = Path(save_dir) if save_dir is not None else out_dir / "plots"
    save.mkdir(parents=True, exist_ok=True)
    box = _box(out_dir)
    written = []

    def finish(fig, ax, name, title):
        if box is not None:
            ax.set_xlim(box[0], box[1])
            ax.set_ylim(box[2], box[3])
        ax.set_aspect("equal")
        ax.set_title(title)
        fig.tight_layout()
        path = save / name
        fig.savefig(path, dpi=dpi)
        plt.close(fig)
        written.append(path)

    def figure():
        if box is None:
            return plt.subplots(figsize=(8, 4))
        w, h = box[1] - box[0], box[3] - box[2]
        aspect = h / w
        return plt.subplots(figsize=(10, max(2.0, min(10.0, 10 * aspect + 0.8))))

    bodies_series = read_pvd(out_dir / "bodies.pvd") if (out_dir / "bodies.pvd").exists() else []
    last_bodies = _outlines(bodies_series[-1][1]) if bodies_series else []
    fields = read_pvd(out_dir / "fields.pvd") if (out_dir / "fields.pvd").exists() else []
    if fields:
        t_last, f_last = fields[-1]
        m = meshio.read(f_last)
        tri = m.cells_dict["triangle"]
        T = mtri.Triangulation(m.points[:, 0], m.points[:, 1], tri)
        fig, ax = figure()
        ax.triplot(T, color="0.3", linewidth=0.2)
        _draw_bodies(ax, last_bodies)
        finish(fig, ax, "mesh.png", f"mesh: {len(m.points)} vertices, {len(tri)} triangles")

        u = m.point_data["velocity"]
        speed = np.hypot(u[:, 0], u[:, 1])
        fig, ax = figure()
        tc = ax.tripcolor(T, speed, shading="gouraud", cmap="viridis")
        fig.colorbar(tc, ax=ax, label="|u|", shrink=0.8)
        xmin, xmax = m.points[:, 0].min(), m.points[:, 0].max()
        ymin, ymax = m.points[:, 1].min(), m.points[:, 1].max()
        nx = 200
        ny = max(20, int(nx * (ymax - ymin) / (xmax - xmin)))
        X, Y = np.meshgrid(np.linspace(xmin, xmax, nx), np.linspace(ymin, ymax, ny))
        U = mtri.LinearTriInterpolator(T, u[:, 0])(X, Y)
        V = mtri.LinearTriInterpolator(T, u[:, 1])(X, Y)
        if np.ma.count(U) > 4 and float(np.ma.max(np.hypot(U, V))) > 0:
            ax.streamplot(X, Y, U.filled(np.nan), V.filled(np.nan), color="w", linewidth=0.5, density=1.2,
                          arrowsize=0.6)
        _draw_bodies(ax, last_bodies)
        finish(fig, ax, "velocity.png", f"velocity magnitude and streamlines, t = {t_last:.4g}")

        fig, ax = figure()
        tc = ax.tripcolor(T, m.point_data["pressure"], shading="gouraud", cmap="RdBu_r")
        fig.colorbar(tc, ax=ax, label="p (dynamic)", shrink=0.8)
        _draw_bodies(ax, last_bodies)
        finish(fig, ax, "pressure.png", f"pressure (dynamic), t = {t_last:.4g}")

    if bodies_series:
        fig, ax = figure()
        first = _outlines(bodies_series[0][1])
        _draw_bodies(ax, first, facecolor="none", edgecolor="0.6", linestyle="--")
        _draw_bodies(ax, last_bodies, facecolor="tab:orange", alpha=0.8)
        finish(fig, ax, "bodies.png", f"bodies at t = {bodies_series[0][0]:.4g} (dashed) and "
                                      f"t = {bodies_series[-1][0]:.4g}")

    h = read_history(out_dir)
    if len(h["t"]):
        fig, ax = figure()
        ids = np.unique(h["id"])
        many = len(ids) > 50
        for i in ids[:: max(1, len(ids) // 200)]:  # at most ~200 paths drawn
            sel = h["id"] == i
            ax.plot(h["x"][sel], h["y"][sel], linewidth=0.6 if many else 1.2)
        _draw_bodies(ax, last_bodies, facecolor="none", edgecolor="k", linewidth=0.3)
        finish(fig, ax, "trajectories.png", f"trajectories of {len(ids)} body centres")
    return written
