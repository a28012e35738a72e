"""How a scene is run: the fluid mesh (:class:`MeshSpec`), the time stepping
(:class:`TimeSpec`) and what is written (:class:`OutputSpec`).

Units: none built in; every value is in the one consistent system the user picks (see
:mod:`fluidem.scene`).  Every user-typed name goes through :mod:`fluidem.names` and is
stored canonically; every bad value raises :class:`fluidem.errors.SceneError` (a
``ValueError``) in the one format of :mod:`fluidem.validate`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .. import names
from ..errors import SceneError
from ..validate import boolean, check_keys, fail, integer, nonnegative, number, pair, positive

__all__ = ["MeshSpec", "TimeSpec", "OutputSpec"]


@dataclass
class MeshSpec:
    """Fluid mesh: target edge length ``h`` (length) and optional grading.

    ``h`` not given: from the scene's scale, ``min(L / 20, d / 4)`` with ``L`` the box's
    shorter side and ``d`` the smallest body's bounding diameter (:func:`default_h`; 0.05 for
    a 2 × 1 box with a disk of radius 0.1); the plan names it.

    ``grading = {region = [xmin, xmax, ymin, ymax] | "bodies", growth = g, h_max = H}``: size
    ``h`` in the region, growing by ``g`` per cell away from it up to ``H`` (default 8h).
    ``strategy`` (``"drag"``, ``"regenerate"`` or ``"fixed"``, see ``names.meaning("strategy",
    ...)``) and ``retriangulate_every`` (steps) apply to a moving mesh, and ``repair``: before a
    re-triangulation for element quality, move the few nodes around the degraded elements
    instead (:mod:`fluidem.mesh.repair`, fields transferred at the moved nodes); ``curved``
    meshes disks as circles.
    """

    h: float | None = None
    grading: dict | None = None
    strategy: str = "drag"
    retriangulate_every: int = 30
    repair: bool = False
    curved: bool = True

    KEYS = ("h", "grading", "strategy", "retriangulate_every", "repair", "curved")
    #: keys of the ``grading`` table
    GRADING_KEYS = ("region", "growth", "h_max")

    def validate(self, where="mesh"):
        self.h = positive(f"{where}.h", self.h, error=SceneError)
        if self.grading is not None:
            g = self.grading
            check_keys(g, self.GRADING_KEYS, f"{where}.grading", error=SceneError)
            region = g.get("region", "bodies")
            if region != "bodies":
                if (not isinstance(region, (list, tuple)) or len(region) != 4
                        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in region)
                        or not (region[1] > region[0] and region[3] > region[2])):
                    raise fail(f"{where}.grading.region", region,
                               "'bodies' or [xmin, xmax, ymin, ymax] with xmax > xmin and ymax > ymin", SceneError)
                region = tuple(float(v) for v in region)
            growth = number(f"{where}.grading.growth", g.get("growth", 1.2), "a number >= 1", lo=1.0, error=SceneError)
            h_max = number(f"{where}.grading.h_max", g.get("h_max", 8.0 * self.h), f"a number >= h = {self.h}",
                            lo=self.h, error=SceneError)
            self.grading = {"region": region, "growth": growth, "h_max": h_max}
        self.strategy = names.lookup("strategy", self.strategy, f"{where}.strategy", SceneError)
        self.retriangulate_every = integer(f"{where}.retriangulate_every", self.retriangulate_every, error=SceneError)
        self.repair = boolean(f"{where}.repair", self.repair, error=SceneError)
        self.curved = boolean(f"{where}.curved", self.curved, error=SceneError)


@dataclass
class TimeSpec:
    """Time step ``dt`` and end time ``t_end`` (time units); the run takes round(t_end/dt) steps.
    ``scheme``: the BDF formula of the fluid (``names.meaning("time scheme", ...)``); ``"auto"``
    is BDF3 on a fixed mesh (DFG 2D-2: 8x smaller errors than BDF2 at the same dt) and BDF2 when
    the mesh moves."""

    dt: float = 1e-3
    t_end: float = 1.0
    scheme: str = "auto"

    KEYS = ("dt", "t_end", "scheme")

    def validate(self, where="time"):
        self.scheme = names.lookup("time scheme", self.scheme, f"{where}.scheme", SceneError)
        self.dt = positive(f"{where}.dt", self.dt, error=SceneError)
        self.t_end = positive(f"{where}.t_end", self.t_end, error=SceneError)
        if self.t_end < self.dt * (1 - 1e-9):
            raise fail(f"{where}.t_end", self.t_end, f"a number >= dt = {self.dt}", SceneError)
        n = self.t_end / self.dt
        if abs(n - round(n)) > 1e-6 * max(1.0, n):  # the last step lands on t_end: t_end = n dt
            lo, hi = math.floor(n) * self.dt, math.ceil(n) * self.dt
            raise fail(f"{where}.t_end", self.t_end, f"a whole number of steps dt = {self.dt:g} (e.g. {lo:.10g} or "
                       f"{hi:.10g}), so that the last step lands on t_end", SceneError)

    @property
    def n_steps(self) -> int:
        return max(1, int(round(self.t_end / self.dt)))

    def bdf_scheme(self, moving_mesh: bool) -> str:
        """The BDF formula the fluid uses: ``scheme`` with ``"auto"`` resolved.

        ``"auto"`` is ``"bdf3"`` on a fixed mesh (DFG 2D-2, P3/P2, Δt = 0.005: St and c_D,max
        within 6e-4 against 4e-3 with BDF2 at the same cost) and ``"bdf2"`` on a moving mesh,
        whose transfer and coupling keep two time levels.

        >>> t = TimeSpec()
        >>> t.bdf_scheme(moving_mesh=False), t.bdf_scheme(moving_mesh=True)
        ('bdf3', 'bdf2')
        """
        if self.scheme == "auto":
            return "bdf2" if moving_mesh else "bdf3"
        return self.scheme


@dataclass
class OutputSpec:
    """Output: directory ``dir``; fields and body outlines every ``every`` steps; history every
    ``history_every`` steps; ``fields = false`` writes no fluid fields; ``full_order = false``
    writes the fields at the mesh vertices only (no ``fields_full`` series); ``xdmf = true``
    also collects the field series into one XDMF time series at the end (a mesh built once;
    needs h5py).

    Checkpoints: every ``checkpoint_every`` steps (0: only at the end; not given: about ten a
    run, the newest three kept) and in any case every ``checkpoint_seconds`` of wall-clock
    time (default 600; 0: off), and at the end.

    ``rheology_window = [t0, t1]``: the times over which a Couette cell's effective viscosity
    is averaged (:mod:`fluidem.rheology`; default: the second half of the run), within
    ``[0, time.t_end]``."""

    dir: str = "out"
    every: int = 10
    history_every: int = 1
    checkpoint_every: int | None = None
    fields: bool = True
    checkpoint_seconds: float = 600.0
    full_order: bool = True
    xdmf: bool = False
    rheology_window: tuple | None = None

    KEYS = ("dir", "every", "history_every", "checkpoint_every", "fields", "checkpoint_seconds", "full_order",
            "xdmf", "rheology_window")

    def validate(self, where="output"):
        if not isinstance(self.dir, str) or not self.dir:
            raise fail(f"{where}.dir", self.dir, "a non-empty path string", SceneError)
        self.every = integer(f"{where}.every", self.every, error=SceneError)
        self.history_every = integer(f"{where}.history_every", self.history_every, error=SceneError)
        if self.checkpoint_every is not None:
            self.checkpoint_every = integer(f"{where}.checkpoint_every", self.checkpoint_every, lo=0,
                                            error=SceneError)
        self.checkpoint_seconds = nonnegative(f"{where}.checkpoint_seconds", self.checkpoint_seconds, error=SceneError)
        self.fields = boolean(f"{where}.fields", self.fields, error=SceneError)
        self.full_order = boolean(f"{where}.full_order", self.full_order, error=SceneError)
        self.xdmf = boolean(f"{where}.xdmf", self.xdmf, error=SceneError)
        if self.rheology_window is not None:
            try:
                self.rheology_window = pair(f"{where}.rheology_window", self.rheology_window, error=SceneError)
            except SceneError:
                raise fail(f"{where}.rheology_window", self.rheology_window, "[t0, t1], two finite times within the "
                           "run", SceneError) from None

