"""Run a scene: build only the parts its plan needs, step, record.

:class:`Simulation` takes a :class:`fluidem.scene.Scene`, asks it for its
:class:`~fluidem.scene.Plan` and builds

* a dry scene: no mesh and no fluid solver; bodies move by the DEM when contacts are on,
  or in closed form (``x = x₀ + v₀ t + g t²/2``, ``θ = θ₀ + ω t``) when they are off, so a
  lone body does no contact search at all;
* a fluid scene with fixed (or outline-preserving) bodies: one mesh, built once; Stokes
  (``solve_stokes`` per step, one LU for the whole run since the matrix never changes) or
  Navier–Stokes (``BDF2Stepper``); loads on the bodies by the residual method;
* a Stokes scene with translating prescribed bodies and a single step (quasi-steady at
  one instant): the mesh of the initial geometry.

* a fluid scene whose prescribed bodies move their outlines: the moving mesh
  (:class:`fluidem.mesh.MovingMesh`), ALE Navier–Stokes or quasi-steady Stokes on it
  (:class:`fluidem.coupling.moving_flow.MovingMeshFlow`); without the moving-mesh layer such
  scenes are refused.

The parts live in :mod:`fluidem.coupling` (bodies adapters, boundary conditions, loads, the
fixed- and moving-mesh flows); this module is the loop.  Free bodies in a fluid need the
coupled solver (a later version) and are refused with a ``ValueError`` that says so.

Each step's wall time is a :class:`fluidem.cost.CostSplit` with parts ``bodies``, ``mesh``,
``rebuild``, ``assembly``, ``solve``, ``loads`` and ``output``, reported to a progress
callback and summed in :attr:`RunResult.totals`.

Runs that never lose or silently corrupt a result:

* the output directory belongs to one run (:func:`fluidem.io.prepare_output_dir`): a fresh
  run into another run's output is refused unless ``overwrite`` or ``restart``; ``run.json``
  records the scene and how far the run got;
* after every step :class:`fluidem.state_checks.StateCheck` checks the state (non-finite
  values, overlaps deeper than half a body's size, a runaway flow); a bad step is
  never recorded;
* checkpoints (:mod:`fluidem.checkpoint`: npz + JSON, loading never executes code) are
  written atomically at ``output.checkpoint_every`` steps (default: about ten a run) and
  every ``output.checkpoint_seconds`` of wall-clock time; on SIGINT/SIGTERM (after the step
  in progress) or an error inside a step the state of the last good step is checkpointed,
  the outputs are closed and :class:`RunStopped` says where and how to continue;
* a restart may change only ``time.t_end`` and ``[output]`` (:func:`scene_changes` lists
  anything else), whatever the scene file is called; the time axis stays ``t = step dt``.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .coupling.bodies import DEMBodies, FlowBodies, KinematicBodies, LinearPath
from .cost import CostSplit
from .diagnostics import RunDiagnostics, oscillation_text
from .errors import FluidemError, InputError
from .geometry import orient_ccw
from .scene import Scene
from .state_checks import StateCheck, StateError
from .validate import integer

__all__ = ["Simulation", "RunResult", "StepTimes", "run", "LinearPath", "RunStopped", "RunWarning", "StateError",
           "scene_changes", "RESTART_MAY_CHANGE", "verbose_line"]

#: a snapshot of the state (to checkpoint if a later step fails) is taken once the steps since the
#: last one took this many times the snapshot's own time: every step for fluid runs, every few
#: steps for cheap DEM steps of many bodies
SNAPSHOT_RATIO = 20.0

#: parts of a run's state whose sizes change as it goes (contact lists, spring histories, neighbour pairs)
_VARIABLE_STATE = (".contacts", "._hist.", "._nbr[", "_pairs", ".springs")

#: smallest triangle angle (degrees) of a freshly built mesh before a warning
MIN_ANGLE = 5.0

#: Former name of the per-step cost record (now :class:`fluidem.cost.CostSplit`; parts read as attributes).
StepTimes = CostSplit


#: Failures a restart from the last checkpoint can get past: they come from the machine (a full disk,
#: an unwritable folder, memory), not from the scene and its state, which a restart replays exactly.
TRANSIENT_FAILURES = (OSError, MemoryError)


@dataclass
class RunResult:
    """Outcome of :meth:`Simulation.run`: steps taken, final time, output directory, timings.

    ``totals`` is a :class:`fluidem.cost.CostSplit`: seconds per part summed over the steps
    of this run, counter ``steps``.
    """

    steps: int
    t: float
    out_dir: str | None
    wall_s: float
    dofs: int = 0
    totals: CostSplit = field(default_factory=CostSplit)
    geometry: str = ""

    def __str__(self):
        s = f"{self.steps} steps to t = {self.t:.6g} in {self.wall_s:.2f} s"
        if self.dofs:
            s += f", {self.dofs} DOFs ({self.geometry} geometry)"
        if self.out_dir:
            s += f"; output in {self.out_dir}"
        return s


# ---------------------------------------------------------------------------------------
# the driver
# ---------------------------------------------------------------------------------------
class Simulation:
    """Run a :class:`~fluidem.scene.Scene`, building only what its plan needs.

    Parameters
    ----------
    scene : Scene, dict, str or Path
        A scene, a scene as a dict (:meth:`Scene.from_dict`) or the path of a TOML scene file.

    Attributes
    ----------
    plan : Plan
    counters : dict
        Parts built and work done: ``triangulations``, ``fluid_solvers``, ``dem``,
        ``steps``, ``dem_substeps``.
    flow : object or None
        The fluid part (``None`` for a dry scene).

    Raises
    ------
    ValueError
        A scene this version cannot run (``plan.unsupported``: a mesh estimated above the
        machine's memory, a fixed mesh under a moving outline, periodic sides in a dry scene,
        ...), with the reasons, before anything is built.

    Examples
    --------
    >>> from fluidem import scene, simulation
    >>> s = scene.Scene.from_dict({"gravity": [0, -10], "domain": {"box": [0, 1, 0, 1]},
    ...     "bodies": [{"shape": "disk", "radius": 0.05, "position": [0.5, 0.8]}],
    ...     "time": {"dt": 0.01, "t_end": 0.1}})
    >>> sim = simulation.Simulation(s)
    >>> r = sim.run(out_dir=None)
    >>> round(float(sim.bodies.positions[0, 1]), 6)   # 0.8 - 10 * 0.1**2 / 2
    0.75
    """

    def __init__(self, scene):
        if isinstance(scene, dict):
            scene = Scene.from_dict(scene)
        elif isinstance(scene, (str, os.PathLike)):
            scene = Scene.from_toml(scene)
        elif not isinstance(scene, Scene):
            raise InputError(f"Simulation(scene = {str(scene)[:60]!r}): expected a Scene, a scene dict or the path "
                             "of a TOML scene file")
        self.scene = scene
        self.plan = scene.plan()
        if self.plan.unsupported:
            raise ValueError("this scene cannot run yet: " + "; ".join(self.plan.unsupported))
        self.counters = {"triangulations": 0, "fluid_solvers": 0, "dem": 0, "steps": 0, "dem_substeps": 0}
        self.step_index = 0
        self.t = 0.0
        self.flow = None
        #: the numerical health of the run's steps (:mod:`fluidem.diagnostics`); ``enabled = False`` skips it
        self.diagnostics = RunDiagnostics()
        self.events = [("built", f"plan: mesh {self.plan.mesh}, contacts {self.plan.on('contacts')}")]
        if self.plan.on("contacts") and scene.fluid is None:
            self.bodies = DEMBodies(scene)
            self.counters["dem"] += 1
        elif scene.fluid is not None and any(b.motion == "free" for b in scene.bodies):
            self.bodies = FlowBodies(scene)
        else:
            self.bodies = KinematicBodies(scene)
        if scene.fluid is not None:
            with self.diagnostics.watching():  # an LU of the set-up (Stokes mobility) goes into step 1's record
                if isinstance(self.bodies, FlowBodies):
                    from .coupling.free_flow import FreeBodyFlow

                    self.flow = self.bodies.flow = FreeBodyFlow(scene, self)
                elif self.plan.mesh == "moving":
                    from .coupling.moving_flow import MovingMeshFlow

                    self.flow = MovingMeshFlow(scene, self)
                else:
                    from .coupling.fixed_flow import FixedMeshFlow

                    self.flow = FixedMeshFlow(scene, self)
            self.events.append(("mesh", ("moving, initial: " if self.plan.mesh == "moving" else "built once: ")
                                + f"{self.flow.mesh.t.shape[1]} triangles, "
                                        f"{self.flow.dofs} DOFs, {'curved' if self.flow.curved else 'polygonal'}"))
            self._warn_degenerate()
        for w in self.plan.warnings:
            self.events.append(("warning", w))
            warnings.warn(w, RunWarning, stacklevel=2)

    def _warn_degenerate(self) -> None:
        """A warning (and an event) when the mesh just built has triangles with angles below :data:`MIN_ANGLE`."""
        from .mesh.quality import mesh_quality

        m = self.flow.mesh
        q = mesh_quality(m.p[:, :m.nvertices].T, _ccw(m))
        if q.min_angle < MIN_ANGLE:
            w = (f"the mesh has degenerate triangles: smallest angle {q.min_angle:.2g}° (warned below {MIN_ANGLE:g}°) "
                 f"among {q.n_triangles} triangles; a body thinner than mesh.h = {self.scene.mesh.h:g} or a narrow "
                 "gap: refine there (mesh.grading) or thicken the body")
            self.plan.warnings.append(w)

    # -- state ------------------------------------------------------------------------------
    def _state(self) -> dict:
        """The run's state: bodies, flow and counters (plain data, arrays and fluidem objects)."""
        loads = getattr(self, "last_loads", None)
        return {"bodies": self.bodies.get_state(), "flow": self.flow.get_state() if self.flow else None,
                "counters": dict(self.counters), "loads": None if loads is None else list(loads)}

    def _header(self) -> dict:
        """What a checkpoint carries beside the state: the scene, dt and the plan it ran with."""
        from .version import __version__

        return {"scene": self.scene.to_dict(), "dt": self.scene.time.dt, "fluidem": __version__,
                "plan": {"mesh": self.plan.mesh, "contacts": self.plan.on("contacts"), "n_steps": self.plan.n_steps,
                         "bodies": type(self.bodies).__name__,
                         "flow": type(self.flow).__name__ if self.flow is not None else None}}

    def _snapshot(self) -> tuple:
        """``(step, t, (tree, arrays))``: a copy of the state now, to checkpoint if a later step fails."""
        from .checkpoint import encode

        arrays: list = []
        return self.step_index, self.t, (encode(self._state(), arrays, copy=True), arrays)

    def restore(self, checkpoint, allow_pickle: bool = False) -> Path:
        """Continue from a checkpoint file, or from the newest valid checkpoint of an output directory.

        What the checkpoint holds is checked against the scene before the run continues: each
        part must be of the kind and fluidem class a fresh state of this scene has, the arrays
        of the bodies must have their shapes (:func:`fluidem.checkpoint.mismatches`), and the
        restored bodies and flow must be finite and of the scene's sizes.  In a directory a
        checkpoint that fails (damaged, crafted or edited) is skipped with a
        :class:`RunWarning` and the previous one is used.  The scene may differ from the
        checkpoint's only in ``time.t_end``, ``[output]``, its name and description; when the
        longer ``t_end`` switches contacts on, the DEM continues the closed-form motion.
        Returns the checkpoint used.

        Raises
        ------
        fluidem.errors.InputError
            A different scene (the message lists each change), a checkpoint beyond ``t_end``,
            or a plan that needs another kind of flow; :class:`fluidem.checkpoint.CheckpointError`
            for a damaged or missing file, or a directory without a valid checkpoint.
        """
        from .checkpoint import CheckpointError, checkpoint_files
        from .io import latest_checkpoint, load_checkpoint

        path = Path(checkpoint)
        # what every checkpoint is checked against: the state of the scene as built, taken before any
        # checkpoint (which may fail half-way) is applied
        template = {"bodies": self.bodies.get_state(), "flow": self.flow.get_state() if self.flow else None}
        if not path.is_dir():
            self._apply_checkpoint(path, load_checkpoint(path, allow_pickle=allow_pickle), template)
            return path
        files = checkpoint_files(path) or [latest_checkpoint(path)]
        bodies, counters = self.bodies, dict(self.counters)
        skipped = []
        for f in files:
            try:
                self._apply_checkpoint(f, load_checkpoint(f), template)
            except CheckpointError as exc:
                skipped.append(str(exc))
                self.bodies, self.counters = bodies, dict(counters)  # the next one applies to the scene's own
                continue
            for why in skipped:
                warnings.warn(f"{why}; continuing from the previous valid checkpoint {str(f)!r}", RunWarning,
                              stacklevel=3)
            return f
        raise CheckpointError(f"no valid checkpoint in {str(path / 'checkpoints')!r}: " + "; ".join(skipped))

    def _apply_checkpoint(self, path: Path, data: dict, template: dict) -> None:
        """Set the run's state from a loaded checkpoint of this scene, checked against ``template``
        (the fresh state: bodies and flow; see :meth:`restore`)."""
        from .checkpoint import CheckpointError, mismatches

        sc = self.scene
        changes = scene_changes(data.get("scene") or {}, sc.to_dict())
        if changes:
            raise InputError(f"checkpoint {str(path)!r} belongs to a different scene: changed "
                             + "; ".join(changes) + "; a restart may change only time.t_end and [output] (anything "
                             "else is a new run: --overwrite or another --out)")
        try:
            step, t = int(data["step"]), float(data["t"])
        except (KeyError, TypeError, ValueError):
            raise CheckpointError(f"checkpoint {str(path)!r} has no valid step and time") from None
        if step > self.plan.n_steps:
            raise InputError(f"time.t_end = {sc.time.t_end:g}: the checkpoint {str(path)!r} is at t = {t:g} (step "
                             f"{step}); expected a t_end of at least {t:g}")
        flow_kind = type(self.flow).__name__ if self.flow is not None else None
        old = data.get("plan") or {}
        if old.get("flow", flow_kind) != flow_kind:
            raise InputError(f"time.t_end = {sc.time.t_end:g}: the longer run needs a {self.plan.mesh!r} mesh, the "
                             f"checkpoint {str(path)!r} holds a {old.get('mesh')!r} one; run the longer scene from the "
                             "start (--overwrite)")
        n, n_free = len(sc.bodies), sum(b.motion == "free" for b in sc.bodies)

        def per_body(at, shape):  # arrays of the bodies keep their shape; contact lists vary
            return (at.startswith(("state.bodies.", "state.flow.bodies.")) or at.endswith(".mm.poses")) and \
                (n in shape or n_free in shape) and not any(v in at for v in _VARIABLE_STATE)

        state = {k: data.get(k) for k in ("bodies", "flow")}
        if isinstance(self.bodies, DEMBodies) != ("dem" in (state["bodies"] or {})):
            template = {**template, "bodies": None}  # a longer t_end switched contacts on (or off): converted below
        bad = mismatches(state, template, exact_shape=per_body)
        if bad:
            raise CheckpointError(f"checkpoint {str(path)!r} does not fit the scene: " + "; ".join(bad))
        try:
            self._set_state(state["bodies"], state["flow"], step)
            self._check_restored()
        except CheckpointError as exc:
            raise CheckpointError(f"checkpoint {str(path)!r} does not fit the scene: {exc}") from None
        except Exception as exc:  # a part that decodes but does not fit where it goes
            raise CheckpointError(f"checkpoint {str(path)!r} does not fit the scene ({type(exc).__name__}: "
                                  f"{_one_line(exc)[:120]})") from None
        self.step_index = step
        self.t = t
        loads = data.get("loads")
        if loads is not None:
            self.last_loads = (np.asarray(loads[0], float), np.asarray(loads[1], float))

    def _set_state(self, bs: dict, flow_state, step: int) -> None:
        sc = self.scene
        if isinstance(self.bodies, DEMBodies) and "dem" not in bs:
            kin = KinematicBodies(sc)
            kin.set_state(bs)
            self.bodies = DEMBodies.from_kinematic(sc, kin)
            self.events.append(("plan", f"from step {step} contacts are on: the DEM continues the closed-form motion"))
        elif isinstance(self.bodies, KinematicBodies) and "dem" in bs:
            dem = DEMBodies.__new__(DEMBodies)
            dem.n = len(sc.bodies)
            dem.set_state(bs)
            self.bodies = dem
        else:
            self.bodies.set_state(bs)
        if self.flow is not None:
            self.flow.set_state(flow_state)

    def _check_restored(self) -> None:
        """The restored bodies and flow have the scene's sizes and finite values (else CheckpointError)."""
        from .checkpoint import CheckpointError

        n, b = len(self.scene.bodies), self.bodies
        parts = [("positions", b.positions, (n, 2)), ("angles", b.angles, (n,)),
                 ("velocities", b.velocities, (n, 2)), ("omegas", b.omegas, (n,))]
        if self.flow is not None:
            parts.append(("flow", self.flow.x, (int(self.flow.dofs),)))
        for name, a, shape in parts:
            a = np.asarray(a)
            if a.shape != shape or a.dtype.kind != "f" or not np.isfinite(a).all():
                raise CheckpointError(f"{name} of shape {a.shape}" + ("" if a.shape != shape or a.dtype.kind != "f"
                                                                      else " with non-finite values")
                                      + f" (expected finite numbers of shape {shape})")

    def _record(self, writer, fields: bool, last: bool = False):
        """Loads of the step just taken; with a writer its history rows and (``fields``) its fields.
        Returns the seconds the loads took."""
        b = self.bodies
        F, T, cnt = b.loads()
        tl = time.perf_counter()
        if self.flow is not None and len(self.scene.bodies) and self.step_index > 0:
            F, T = self.flow.loads()  # at step 0 the flow is only its initial data: no loads
        t_loads = time.perf_counter() - tl
        self.last_loads = (F, T)
        if writer is None:
            return t_loads
        sc = self.scene
        pos, ang, vel, om = b.positions, b.angles, b.velocities, b.omegas
        if self.step_index % sc.output.history_every == 0 or last:
            writer.history(self.step_index, self.t, self._in_box(pos), ang, vel, om, F, T, cnt, unwrapped=pos)
            t_loads += self._record_sides(writer)
        # what run.json reports if a later step fails: this step, the last good one
        self._recorded = (self.step_index, self.t, pos, ang, vel, om, np.array(F, float), np.array(T, float))
        if fields:
            self._write_fields(writer)
        return t_loads

    def _in_box(self, positions) -> np.ndarray:
        """Body positions ``(n, 2)`` wrapped into the box across its periodic sides (the bodies keep
        continuous, unwrapped positions: a body that crossed a side is in the box again here)."""
        from .coupling.boundary import period_of_scene
        from .geometry import wrap_into_box

        return wrap_into_box(positions, self.scene.domain.box, period_of_scene(self.scene))

    def _record_sides(self, writer) -> float:
        """The force of the fluid on every wall, moving wall and inflow side into sides.csv (from step 1:
        at step 0 the flow is only its initial data).  Returns the seconds it took."""
        if self.flow is None or self.step_index == 0:
            return 0.0
        names = [s for s in ("bottom", "right", "top", "left")
                 if self.scene.domain.side(s).type in ("wall", "moving-wall", "inflow")]
        if not names:
            return 0.0
        from .fluid.forces import side_loads

        t0 = time.perf_counter()
        F = side_loads(self.flow.space, self.flow.residual(), names, rho=self.scene.fluid.density)
        seconds = time.perf_counter() - t0
        writer.sides(self.step_index, self.t, names, F)
        return seconds

    def _write_fields(self, writer) -> None:
        """Body outlines and (fluid scenes) the fields of the current state into the series."""
        sc, b = self.scene, self.bodies
        pos, ang = self._in_box(b.positions), b.angles
        outlines = [sb.world_vertices(sc.default_segments(sb), pos[k], ang[k]) for k, sb in enumerate(sc.bodies)]
        if outlines:
            writer.bodies(self.step_index, self.t, outlines, b.velocities, b.omegas)
        if self.flow is not None and sc.output.fields:
            from .io import fluid_point_data, full_order_fields

            m = self.flow.mesh
            writer.fields(self.step_index, self.t, m.p[:, :m.nvertices].T, _ccw(m),
                          fluid_point_data(self.flow.space, self.flow.x, sc.fluid.density))
            if sc.output.full_order:
                writer.fields_full(self.step_index, self.t,
                                   *full_order_fields(self.flow.space, self.flow.x, sc.fluid.density))
        self._fields_step = self.step_index

    def _advance(self, dt: float, writer, check: StateCheck) -> CostSplit:
        """One step of the bodies and the flow, then the state checks; the step is not recorded yet."""
        st = CostSplit()
        t_new = (self.step_index + 1) * dt
        b = self.bodies
        with st.timer("bodies"):
            if isinstance(b, DEMBodies):
                with np.errstate(all="ignore"):  # a bad state is reported by the checks below, by body
                    b.step(dt)
            else:
                b.step(dt)
        check.bodies(b.positions, b.angles, b.velocities, b.omegas, t_new)
        if isinstance(b, DEMBodies):
            check.walls(b.dem.world_vertices(), b.dem.walls, t_new)
            check.overlaps(b.dem.contacts, t_new)
        if self.flow is not None:
            with self.diagnostics.watching():  # the solvers report each LU and solve of the step
                self.flow.step(dt)
            st += self.flow.last_cost
            x, nd = self.flow.x, self.flow.space.ub.nodal_dofs
            if not np.isfinite(x).all():
                x = np.where(np.isfinite(x), x, np.nan)
            check.flow(x[nd[0]], x[nd[1]], self.flow.mesh.p, t_new, x=x)
        return st

    def summary(self, wall_s: float | None = None) -> dict:
        """The run's summary quantities, as ``run.json`` records them at the end of a run.

        Returns
        -------
        dict
            ``steps``, ``t`` (time), ``wall_s`` (wall seconds of the stepping loop of this run,
            if given); fluid scenes: ``dofs``, ``triangles``, ``element``; ``bodies``: one entry
            per body (by name, else ``body<k>``) with its final ``x``, ``y`` (length), ``angle``
            (rad), ``vx``, ``vy`` (length/time), ``omega`` (rad/time) and the last recorded load
            ``fx``, ``fy`` (force/depth) and ``torque`` (force*length/depth), the history.csv
            convention.
        """
        rec = getattr(self, "_recorded", None) if getattr(self, "_failed", False) else None
        if rec is None:  # the state now (after a failed step: the last step recorded)
            b, n = self.bodies, len(self.scene.bodies)
            F, T = getattr(self, "last_loads", (np.zeros((n, 2)), np.zeros(n)))
            rec = (self.step_index, self.t, b.positions, b.angles, b.velocities, b.omegas, F, T)
        step, t, pos, ang, vel, om, F, T = rec
        out = {"steps": step, "t": t}
        if wall_s is not None:
            out["wall_s"] = wall_s
        if self.flow is not None:
            out.update(dofs=int(self.flow.dofs), triangles=int(self.flow.mesh.t.shape[1]),
                       element=self.scene.fluid.element)
        bodies = {}
        for k, sb in enumerate(self.scene.bodies):
            name = sb.name or f"body{k}"
            bodies[name] = {"x": float(pos[k, 0]), "y": float(pos[k, 1]), "angle": float(ang[k]),
                            "vx": float(vel[k, 0]), "vy": float(vel[k, 1]), "omega": float(om[k]),
                            "fx": float(F[k, 0]), "fy": float(F[k, 1]), "torque": float(T[k])}
        out["bodies"] = bodies
        return out

    def _run_record(self, out_dir, status: str, n_steps: int, checkpoint=None, message: str = "",
                    totals: CostSplit | None = None, summary: dict | None = None) -> None:
        from .version import __version__
        from .io import HISTORY_UNITS, write_run_record

        sc, dem = self.scene, self.dem_limit()
        write_run_record(out_dir, {
            "format": "fluidem-run-1", "scene": sc.name, "scene_key": scene_key(sc.to_dict()),
            "source": sc.source, "fluidem": __version__, "status": status, "step": self.step_index, "t": self.t,
            "n_steps": n_steps, "dt": sc.time.dt, "t_end": sc.time.t_end,
            "checkpoint": None if checkpoint is None else str(Path(checkpoint).relative_to(out_dir)),
            "message": message, "units": HISTORY_UNITS,
            "pressure": "VTU 'pressure' is dynamic (fluid density x kinematic pressure), 'kinematic_pressure' "
                        "beside it; history loads are dynamic too",
            **({} if totals is None else {"cost": {"seconds": dict(totals.parts), "counts": dict(totals.counts),
                                                   "note": "wall seconds per part summed over this run's steps"}}),
            **({} if summary is None else {"summary": summary}),
            **({} if dem is None else {"dem_sub_step": dem}),
            **({} if self.flow is None or not self.diagnostics.enabled else
               {"diagnostics": self.diagnostics.record()}),
            **self._rheology_record(out_dir, status)})

    def _rheology_record(self, out_dir, status: str) -> dict:
        """``{"rheology": ...}`` for a complete run of a shear cell (:func:`fluidem.rheology.rheology`
        over its sides.csv, restarts included), else ``{}``."""
        from .rheology import rheology, shear_cell

        if status != "complete" or shear_cell(self.scene)[0] is None:
            return {}
        from .io import read_sides

        return {"rheology": rheology(self.scene, read_sides(out_dir))}

    def _check_owner(self, out_dir) -> None:
        """Refuse to continue, in ``out_dir``, a run of another scene."""
        from .io import OutputDirError, read_run_record

        rec = read_run_record(out_dir)
        if rec.get("scene_key") and rec["scene_key"] != scene_key(self.scene.to_dict()):
            raise OutputDirError(f"output directory {str(out_dir)!r} holds a run of another scene "
                                 f"({rec.get('scene')!r}); continue it with its own scene ({str(out_dir)}/scene.toml) "
                                 "or give another --out")

    def _log_mesh_event(self, writer, ev_mesh) -> None:
        """Event-log lines of this step's mesh update: re-triangulation (reason, size, field
        transfer, interpolation noise and force change) and oscillating nodes."""
        if ev_mesh.retriangulated:
            msg = f"reason={ev_mesh.reason} nodes={ev_mesh.n_nodes} triangles={ev_mesh.n_triangles}"
            if self.scene.fluid.model != "stokes":
                how = ("ALE interpolation through the old mesh motion" if ev_mesh.history == "ale" else
                       "interpolation, Eulerian step (old mesh not valid at the new positions)"
                       if ev_mesh.history == "eulerian" else "interpolation")
                msg += f"; fields transferred by {how}"
                if ev_mesh.transfer_change is not None:
                    msg += f"; interpolation noise {100 * ev_mesh.transfer_change:.3g} %"
                if ev_mesh.force_change is not None:
                    msg += f"; force change {100 * ev_mesh.force_change:.3g} %"
            writer.event(self.step_index, self.t, "retriangulation", msg)
            inertial = self.scene.fluid.model != "stokes"
            if ev_mesh.reason == "seam" and inertial and not self.__dict__.get("_seam_warned"):
                self._seam_warned = True
                warnings.warn(f"step {self.step_index}: a body crosses a periodic side in Navier–Stokes flow: the "
                              "forces of the steps it crosses carry an ALE error (a disk at Re 30: up to twice the "
                              "drag at U dt = h/5, 6 % at h/20; docs: moving-mesh, bodies across periodic sides); "
                              "Stokes flow across the sides is accurate", RunWarning, stacklevel=2)
        if len(ev_mesh.oscillating):
            h = self.diagnostics.last
            swing = h.swing if h is not None and h.step == self.step_index else None
            writer.event(self.step_index, self.t, "oscillation",
                         oscillation_text(len(ev_mesh.oscillating), len(self.flow.mm.points), swing))

    def _health(self, writer, ev_mesh) -> None:
        """Close the step's health record (:class:`fluidem.diagnostics.RunDiagnostics`); a threshold
        crossed is a :class:`RunWarning` and a ``health`` line in events.log."""
        d = self.diagnostics
        d.finish_step(self.step_index, self.t, ev_mesh, getattr(self.flow, "mm", None))
        for w in d.check():
            if writer is not None:
                writer.event(self.step_index, self.t, "health", w)
            warnings.warn(w, RunWarning, stacklevel=4)

    # -- per-step report -------------------------------------------------------------------------
    def _linear_solver(self):
        """The linear solver of the last flow step (coupled fluid-body, fluid or Stokes), or None."""
        f = self.flow
        for owner in (getattr(f, "coupled", None), getattr(f, "stepper", None), f):
            s = getattr(owner, "solver", None)
            if s is not None:
                return s
        return None

    def step_info(self) -> dict:
        """What the last step's solvers recorded, for a verbose progress line.

        Returns
        -------
        dict
            ``step``, ``t`` (time); for a fluid scene also ``solver`` (method of the last
            linear solve, :class:`fluidem.fluid.solvers.SolveInfo`), ``iterations`` (its Krylov
            iterations; 0 for a direct solve), ``residual`` (its relative residual),
            ``factorizations`` (LU factorisations so far, if the solver counts them) and ``cfl``
            (Courant number max over elements of |u| Δt / h_e, h_e the longest edge, from the new
            velocity; None for quasi-steady Stokes); for a DEM scene ``contacts`` (contacts at the
            end of the step, body-body and body-wall); with contacts in a fluid ``dem_set_by`` (what
            set the sub-steps of the step's last pass, :meth:`fluidem.coupling.contacts.FluidContacts.sub_steps`);
            ``health`` when the step has something to say (:meth:`fluidem.diagnostics.StepHealth.text`:
            the condition estimate of a new LU and its growth, the interpolation noise of a
            re-triangulation, oscillating nodes).
        """
        out = {"step": self.step_index, "t": self.t}
        if self.flow is not None:
            s = self._linear_solver()
            info = getattr(s, "last_info", None)
            out.update(solver=getattr(info, "method", None), iterations=getattr(info, "iterations", None),
                       residual=getattr(info, "relative_residual", None),
                       factorizations=getattr(s, "factorizations", None))
            st = getattr(self.flow, "stepper", None)
            out["cfl"] = st._cfl(st.state.u) if st is not None and st.n_steps else None
            h = self.diagnostics.last
            if h is not None and h.step == self.step_index and h.text():
                out["health"] = h.text()
        if isinstance(self.bodies, DEMBodies):
            out["contacts"] = len(self.bodies.dem.contacts.i)
        contacts = getattr(self.flow, "contacts", None)
        if contacts is not None and contacts.last_set_by:
            out["dem_set_by"] = contacts.last_set_by
        return out

    def _dem(self):
        """The DEM that moves the bodies (dry scenes) or sub-steps their contacts in a fluid, or None."""
        if isinstance(self.bodies, DEMBodies):
            return self.bodies.dem
        contacts = getattr(self.flow, "contacts", None)
        return getattr(contacts, "dem", None)

    def dem_limit(self) -> dict | None:
        """The DEM's largest stable sub-step and what sets it: ``{"dt_max": time, "set_by": text}``
        (the contact law's E or the repulsion's stiffness at contact, with the lightest free body),
        or None for a scene without a DEM.  In a fluid a pass takes it only where an overlap may form;
        elsewhere the stiffness in play sets fewer sub-steps
        (:meth:`fluidem.coupling.contacts.FluidContacts.sub_steps`)."""
        d = self._dem()
        if d is None:
            return None
        dt = float(d.dt_max)
        return {"dt_max": dt if np.isfinite(dt) else None, "set_by": getattr(d, "dt_max_set_by", "")}

    # -- running ---------------------------------------------------------------------------------
    def run(self, out_dir="scene", restart=None, progress=None, n_steps: int | None = None,
            overwrite: bool = False, allow_pickle: bool = False, verbose=False) -> RunResult:
        """Step to ``time.t_end`` (or ``n_steps`` steps in total), writing output to ``out_dir``.

        Parameters
        ----------
        out_dir : str, Path or None
            Output directory; ``"scene"`` takes ``[output] dir``; ``None`` writes nothing.  A
            directory holding another run's output is refused unless ``overwrite`` or ``restart``,
            and so is one another run is writing now (:class:`fluidem.io.RunLock`, held for the
            whole run).
        restart : str, Path or True, optional
            Continue from a checkpoint file, or from the newest valid checkpoint in ``out_dir``
            (``True``); the history is cut back to the checkpoint and continued.
        progress : callable, optional
            ``progress(step, n_steps, t, cost)`` after every step, ``cost`` the step's
            :class:`~fluidem.cost.CostSplit`.
        n_steps : int, optional
            Stop after this many steps in total (the plan's ``round(t_end/dt)`` by default, also
            the most allowed).
        overwrite : bool
            Clear the run output already in ``out_dir`` first: the entries its ``run.json``
            lists (:data:`fluidem.io.OUTPUT_ENTRIES`), nothing else.
        allow_pickle : bool
            Accept a pickle checkpoint of an earlier version as ``restart`` (only for your own files).
        verbose : bool or file-like
            One plain-text line per step (to stderr, or to the given stream): step, time, the
            linear solver's method, Krylov iterations and relative residual, the CFL number, the
            step's health when it has something to say (condition estimate of a new LU, noise of a
            re-triangulation, oscillating mesh nodes: :mod:`fluidem.diagnostics`) and the step's
            cost split (:func:`verbose_line` of :meth:`step_info`).

        Raises
        ------
        RunStopped
            On SIGINT/SIGTERM (after the step in progress; a second Ctrl-C stops at once) or an
            error inside a step, with output: the outputs are closed, the state of the last
            good step is checkpointed, and the message says where and how to continue.
            Without output the error itself propagates.
        """
        from .io import RunLock

        sc = self.scene
        if isinstance(out_dir, str) and out_dir == "scene":
            out_dir = sc.output.dir
        if out_dir is not None and (not isinstance(out_dir, (str, os.PathLike)) or not str(out_dir).strip()):
            raise InputError(f"out_dir = {out_dir!r}: expected the path of a directory (str or Path), 'scene' for "
                             "[output] dir, or None to write nothing")
        if progress is False:
            progress = None
        if progress is not None and not callable(progress):
            raise InputError(f"progress = {progress!r}: expected None or a callable progress(step, n_steps, t, cost)")
        if verbose is not False and verbose is not None:
            if verbose is not True and not callable(getattr(verbose, "write", None)):
                raise InputError(f"verbose = {verbose!r}: expected True, False or a text stream with a write method")
            stream = sys.stderr if verbose is True else verbose
            progress = _Verbose(self, stream, progress)
        restarting = restart is not None and restart is not False
        if restarting and overwrite:
            raise InputError("restart and overwrite exclude each other: restart continues the run in the output "
                             "directory, overwrite clears it")
        if restart is True and out_dir is None:
            raise InputError("restart = True needs an output directory with checkpoints")
        if n_steps is not None:
            n_steps = integer("n_steps", n_steps, lo=1)
            if n_steps > self.plan.n_steps:
                raise InputError(f"n_steps (--steps) = {n_steps}: the scene has {self.plan.n_steps} steps to "
                                 f"time.t_end = {sc.time.t_end:g}; expected at most {self.plan.n_steps} (raise "
                                 "time.t_end to run longer)")
        if out_dir is not None and self.flow is not None and sc.output.fields and sc.output.xdmf:
            from .io import require_h5py  # before anything is written, the folder included

            require_h5py("output.xdmf = true")
            if self.plan.mesh == "moving":
                raise InputError("output.xdmf = true: an XDMF time series holds one mesh, and this scene's mesh "
                                 "moves; set it to false (the VTU series fields_full.pvd has every step, "
                                 "fluidem.io.read_fields reads it)")
        lock = None if out_dir is None else RunLock(out_dir).acquire()  # one writer, from before the first read
        try:
            return self._run(out_dir, restart if restart is not True else out_dir, progress, n_steps, overwrite,
                             allow_pickle)
        finally:
            if lock is not None:
                lock.release()

    def _run(self, out_dir, restart, progress, n_steps, overwrite: bool, allow_pickle: bool) -> RunResult:
        """:meth:`run` with its arguments checked, holding the output directory's lock."""
        from .io import OutputWriter, prepare_output_dir

        sc = self.scene
        restarting = restart is not None and restart is not False
        ck_used = None
        if restarting:
            n_events = len(self.events)
            ck_used = self.restore(restart, allow_pickle=allow_pickle)  # lists any change of the scene
            if out_dir is not None and Path(out_dir).is_dir():
                self._check_owner(out_dir)  # a checkpoint from elsewhere: the folder must be this scene's
        N = self.plan.n_steps if n_steps is None else n_steps
        xdmf = out_dir is not None and self.flow is not None and sc.output.fields and sc.output.xdmf
        writer = None
        if out_dir is not None:
            prepare_output_dir(out_dir, "restart" if restarting else ("overwrite" if overwrite else "new"))
            writer = OutputWriter(out_dir, restart_step=self.step_index if restarting else None)
            sc.to_toml(Path(out_dir) / "scene.toml")  # the scene as run (on a restart: with its new t_end)
            if not restarting:
                for kind, msg in self.events:
                    writer.event(0, 0.0, kind, msg)
                if self.flow is not None:
                    from .mesh.quality import mesh_quality

                    m = self.flow.mesh
                    writer.mesh_quality(0, 0.0, mesh_quality(m.p[:, :m.nvertices].T, _ccw(m)))
            else:
                writer.event(self.step_index, self.t, "restart", f"from {ck_used}")
                for kind, msg in self.events[n_events:]:
                    writer.event(self.step_index, self.t, kind, msg)
            self._run_record(out_dir, "running", N)
        dt = sc.time.dt
        ev = sc.output.every
        ck, ck_wall = sc.output.checkpoint_every, sc.output.checkpoint_seconds
        keep = None
        if ck is None:  # the default cadence: about ten checkpoints a run, the newest three kept
            ck, keep = max(1, -(-N // 10)), 3
        check = StateCheck.for_scene(sc)
        totals = CostSplit()
        wall0 = time.perf_counter()
        last_ck_wall = wall0
        stop = None  # (kind, signal name, exception)
        snap = None
        last_ck = None
        guard = _SignalGuard()
        try:
            with guard:
                if self.step_index == 0 and writer is not None:
                    self._record(writer, fields=True)
                if writer is not None:
                    snap = self._snapshot()
                snap_s, since = 0.0, 0.0  # seconds of the last snapshot, of the steps since
                while self.step_index < N:
                    if guard.signal:
                        stop = ("interrupt", guard.signal, None)
                        break
                    t_step = time.perf_counter()
                    try:
                        st = self._advance(dt, writer, check)
                    except KeyboardInterrupt:
                        if writer is None:
                            raise
                        stop = ("interrupt", "SIGINT", None)
                        break
                    except Exception as exc:
                        if writer is None:
                            raise
                        self._failed = True  # the state is the failed step's; the last good one is recorded
                        stop = ("error", None, exc, self.step_index + 1)
                        break
                    self.step_index += 1
                    self.counters["steps"] += 1
                    self.t = self.step_index * dt
                    t0 = time.perf_counter()
                    last = self.step_index == N
                    t_loads = self._record(writer, fields=(self.step_index % ev == 0 or last), last=last)
                    ev_mesh = getattr(self.flow, "last_event", None) if self.flow is not None else None
                    if self.flow is not None:
                        self._health(writer, ev_mesh)
                    if ev_mesh is not None and writer is not None:  # after the loads: the force change is known
                        self._log_mesh_event(writer, ev_mesh)
                    if writer is not None and self.plan.mesh == "moving" and (self.step_index % ev == 0 or last):
                        writer.mesh_quality(self.step_index, self.t, self.flow.mm.quality())
                    if writer is not None:
                        now = time.perf_counter()
                        since += now - t_step
                        due = (ck and self.step_index % ck == 0) or last or (ck_wall and now - last_ck_wall >= ck_wall)
                        if due or since >= SNAPSHOT_RATIO * snap_s:  # snapshots cost at most ~5 % of the steps
                            snap = self._snapshot()
                            snap_s, since = time.perf_counter() - now, 0.0
                        if due:
                            last_ck = writer.checkpoint(self.step_index, self.t, header=self._header(),
                                                        snapshot=snap[2], keep=keep)
                            last_ck_wall = now
                    st.add("loads", t_loads)
                    st.add("output", time.perf_counter() - t0 - t_loads)
                    st.count("steps")
                    totals += st
                    if progress is not None:
                        progress(self.step_index, N, self.t, st)
            if guard.signal and stop is None and self.step_index < N:
                stop = ("interrupt", guard.signal, None)
            if stop is not None and stop[0] == "interrupt" and writer is not None and snap[0] != self.step_index:
                snap = self._snapshot()  # stopped between steps: the state now is good
            if stop is not None and writer is None:
                raise KeyboardInterrupt
        except BaseException as exc:  # outside a step (recording, output, progress)
            if writer is None or isinstance(exc, (SystemExit, GeneratorExit)):
                if writer is not None:
                    writer.close()
                raise
            stop = ("interrupt", "SIGINT", None) if isinstance(exc, KeyboardInterrupt) else \
                ("error", None, exc, max(self.step_index, 1))  # recording the step failed
        if writer is not None:
            if stop is None:
                if xdmf:
                    from .io import write_xdmf

                    try:
                        writer.event(self.step_index, self.t, "xdmf", str(write_xdmf(out_dir).name))
                    except Exception as exc:  # the run's results stand; the series can be written later
                        writer.event(self.step_index, self.t, "xdmf-failed", _one_line(exc))
                        warnings.warn(f"the XDMF time series was not written: {_one_line(exc)}", RunWarning,
                                      stacklevel=2)
                writer.event(self.step_index, self.t, "end", f"{self.counters['steps']} steps this run")
                writer.close()
                self._run_record(out_dir, "complete" if self.step_index >= self.plan.n_steps else "stopped", N,
                                 last_ck, totals=totals, summary=self.summary(time.perf_counter() - wall0))
            else:
                self._stop(writer, out_dir, N, stop, snap, keep, totals, wall0)
        if isinstance(self.bodies, DEMBodies):
            self.counters["dem_substeps"] = self.bodies.substeps
        elif getattr(self.flow, "contacts", None) is not None:
            self.counters["dem_substeps"] = self.flow.contacts.substeps
        return RunResult(self.step_index, self.t, None if out_dir is None else str(out_dir),
                         time.perf_counter() - wall0, self.flow.dofs if self.flow else 0, totals,
                         ("curved" if self.flow.curved else "polygonal") if self.flow else "")

    def _stop(self, writer, out_dir, n_steps, stop, snap, keep, totals, wall0):
        """Close the outputs at the last good step (its fields written, if they were not), checkpoint
        it, record the run's cost and summary, and raise :class:`RunStopped`."""
        kind, sig, exc = stop[:3]
        step, t, snapshot = snap if snap is not None else (self.step_index, self.t, None)
        failed_at = stop[3] if kind == "error" else self.step_index + 1
        try:
            self._last_good_fields(writer, snap)
        except Exception as err:  # e.g. the directory is read-only now
            writer.event(step, t, "fields-failed", _one_line(err))
        path = None
        try:
            if snapshot is not None:
                path = writer.checkpoint(step, t, header=self._header(), snapshot=snapshot, keep=keep)
        except Exception as err:  # the disk is full, say: the older checkpoints stay
            writer.event(step, t, "checkpoint-failed", _one_line(err))
        sc = self.scene
        where = f"checkpoint {str(path)!r}" if path is not None else "no new checkpoint (see events.log)"
        how = f"fluidem run {sc.source or str(Path(out_dir) / 'scene.toml')} --out {out_dir} --restart"
        if kind == "interrupt":
            msg = (f"interrupted by {sig} after step {step} of {n_steps} (t = {t:.6g}); the output holds steps 0 to "
                   f"{step}; {where}; continue with: {how}")
            status, code = "interrupted", 143 if sig == "SIGTERM" else 130
        else:
            what = _one_line(exc)
            if isinstance(exc, OSError):
                what = (f"writing the output failed ({exc.strerror or what}" + (f": {exc.filename!r}" if exc.filename
                                                                                else "")
                        + f"); expected a writable output directory {str(out_dir)!r} with free space")
            msg = (f"step {failed_at} (t = {failed_at * sc.time.dt:.6g}) failed: {what}; the output holds steps 0 to "
                   f"{failed_at - 1}, the last good state "
                   + (f"saved (step {step}) " if step != failed_at - 1 else "") + f"is in {where}")
            if isinstance(exc, TRANSIENT_FAILURES):  # the machine's, not the scene's: a restart may pass
                msg += f"; continue with: {how}"
            elif not isinstance(exc, StateError):
                msg += ("; the failure depends only on the scene and the state, so a --restart from the "
                        "checkpoint repeats it: change what the message names (or time.dt) first")
            status, code = "failed", 3
        writer.event(step, t, status, _one_line(msg))
        writer.event(step, t, "end", f"{self.counters['steps']} steps this run")
        writer.close()
        self._run_record(out_dir, status, n_steps, path, _one_line(msg), totals=totals,
                         summary=self.summary(time.perf_counter() - wall0))
        err = RunStopped(msg, status=status, exit_status=code, checkpoint=path)
        if exc is not None:
            raise err from exc
        raise err


    def _last_good_fields(self, writer, snap) -> None:
        """Write the fields of the last recorded step if its output step did not (after a failed step:
        from the snapshot, when it is of that step)."""
        if getattr(self, "_failed", False):
            rec = getattr(self, "_recorded", None)
            if snap is None or rec is None or snap[0] != rec[0]:
                return
            from .checkpoint import decode

            state = decode(*snap[2])
            self._set_state(state["bodies"], state["flow"], snap[0])
            self._failed = False
        if getattr(self, "_fields_step", None) != self.step_index:
            self._write_fields(writer)


def verbose_line(info: dict, n_steps: int, cost: CostSplit | None = None) -> str:
    """One line for a step: ``step k/N  t = ...  linear <method> it <n> res <r>  CFL <c>  <health>  <cost split>``
    (``<health>``: ``cond1 <κ₁> (x<growth since the first LU>)`` at a new LU, ``noise <n> %`` at a
    re-triangulation, ``osc <k> nodes``; :mod:`fluidem.diagnostics`);
    with contacts in a fluid also ``DEM <n> sub-steps in <p> passes (<what set the last pass's>)``
    (the sub-stepped passes over the step, each of at most ``ceil(dt / dt_max)`` sub-steps:
    :meth:`fluidem.coupling.contacts.FluidContacts.sub_steps`; :meth:`Simulation.dem_limit` says what
    sets ``dt_max``).

    ``info`` as from :meth:`Simulation.step_info`; fields it lacks are left out."""
    parts = [f"step {info['step']}/{n_steps}  t = {info['t']:.6g}"]
    if info.get("solver") is not None:
        lin = f"linear {info['solver']} it {info['iterations']}"
        if info.get("residual") is not None:
            lin += f" res {info['residual']:.2e}"
        if info.get("factorizations") is not None:
            lin += f" LU {info['factorizations']}"
        parts.append(lin)
    if info.get("cfl") is not None:
        parts.append(f"CFL {info['cfl']:.3g}")
    if "contacts" in info:
        parts.append(f"contacts {info['contacts']}")
    if info.get("health"):
        parts.append(info["health"])
    if cost is not None and cost.counts.get("dem_passes"):
        dem = f"DEM {cost.counts['dem_substeps']} sub-steps in {cost.counts['dem_passes']} passes"
        if cost.counts.get("dem_passes_redone"):
            dem += f", {cost.counts['dem_passes_redone']} redone"
        if info.get("dem_set_by"):
            dem += f" ({info['dem_set_by']})"
        if cost.counts.get("contact_unsettled"):
            dem += ", contact load unsettled"
        parts.append(dem)
    if cost is not None:
        parts.append(str(cost))
    return "  ".join(parts)


class _Verbose:
    """A progress callback printing :func:`verbose_line` for every step (then calling ``inner``)."""

    def __init__(self, sim: Simulation, stream, inner=None):
        self.sim, self.stream, self.inner = sim, stream, inner

    def __call__(self, k, n, t, cost):
        print(verbose_line(self.sim.step_info(), n, cost), file=self.stream, flush=True)
        if self.inner is not None:
            self.inner(k, n, t, cost)


class RunWarning(UserWarning):
    """Something a run did that its output should say: a damaged checkpoint skipped, a coarse mesh."""


class RunStopped(FluidemError):
    """A run stopped before its end: interrupted (SIGINT/SIGTERM) or a step failed.

    The :class:`Simulation` itself is left where it stopped (after a failed step: in the bad
    state); continue with a new one, ``Simulation(scene).run(out_dir, restart=True)``.

    Attributes
    ----------
    status : {"interrupted", "failed"}
    exit_status : int
        130 (SIGINT), 143 (SIGTERM) or 3 (a failed step): the command line's exit status.
    checkpoint : Path or None
        The checkpoint of the last good step.
    """

    def __init__(self, message, status="failed", exit_status=3, checkpoint=None):
        super().__init__(message)
        self.status = status
        self.exit_status = exit_status
        self.checkpoint = checkpoint


class _SignalGuard:
    """SIGINT and SIGTERM set :attr:`signal` (the run stops after the step in progress); a second
    SIGINT raises ``KeyboardInterrupt`` at once.  Installed only in the main thread, and not for a
    signal the process ignores."""

    def __init__(self):
        self.signal = None
        self._old = {}

    def __enter__(self):
        import signal
        import threading

        if threading.current_thread() is not threading.main_thread():
            return self
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                old = signal.getsignal(sig)
                if old is signal.SIG_IGN or old is None:
                    continue
                self._old[sig] = signal.signal(sig, self._handle)
            except (ValueError, OSError):  # pragma: no cover - not allowed here
                pass
        return self

    def _handle(self, signum, frame):
        import signal

        name = signal.Signals(signum).name
        if self.signal is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self.signal = name
        print(f"fluidem: {name}: stopping after this step (Ctrl-C again to stop at once)", file=sys.stderr,
              flush=True)

    def __exit__(self, *exc):
        import signal

        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old = {}
        return False


# ---------------------------------------------------------------------------------------
# restart rules
# ---------------------------------------------------------------------------------------
#: scene keys a restart may change (besides every key of [output])
RESTART_MAY_CHANGE = ("name", "description", "time.t_end")


def _flatten(d, prefix="") -> dict:
    if isinstance(d, dict):
        out = {}
        for k, v in d.items():
            out.update(_flatten(v, f"{prefix}.{k}" if prefix else str(k)))
        return out
    if isinstance(d, list) and prefix == "bodies":
        out = {"bodies": f"{len(d)} bodies"}
        for i, v in enumerate(d):
            out.update(_flatten(v, f"bodies[{i}]"))
        return out
    return {prefix: d}


def _fixed(flat: dict) -> dict:
    return {k: v for k, v in flat.items() if k not in RESTART_MAY_CHANGE and k != "output" and
            not k.startswith("output.")}


def scene_changes(old: dict, new: dict) -> list:
    """The changes between two scene dicts (:meth:`Scene.to_dict`) that a restart does not allow.

    Returns ``"key old -> new"`` strings; ``time.t_end``, ``[output]``, ``name`` and
    ``description`` may change, and ``[mesh]`` of a dry scene (which has no mesh).

    Examples
    --------
    >>> scene_changes({"time": {"dt": 0.05, "t_end": 2.0}}, {"time": {"dt": 0.025, "t_end": 4.0}})
    ['time.dt 0.05 -> 0.025']
    """
    a, b = _fixed(_flatten(old)), _fixed(_flatten(new))
    if "fluid" not in old and "fluid" not in new:  # a dry scene has no mesh: [mesh] does not matter
        a, b = ({k: v for k, v in x.items() if not k.startswith("mesh.")} for x in (a, b))
    missing = "(absent)"
    keys = list(a) + [k for k in b if k not in a]
    return [f"{k} {a.get(k, missing)!r} -> {b.get(k, missing)!r}".replace("'(absent)'", missing)
            for k in keys if a.get(k, missing) != b.get(k, missing)]


def scene_key(d: dict) -> str:
    """A digest of what a restart must keep of a scene dict (see :func:`scene_changes`)."""
    import hashlib
    import json

    flat = _fixed(_flatten(d))
    return hashlib.sha256(json.dumps(flat, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _one_line(exc) -> str:
    return " ".join(str(exc).splitlines()) or type(exc).__name__


def _ccw(mesh) -> np.ndarray:
    """Triangles (m, 3) of a scikit-fem mesh, counter-clockwise (scikit-fem sorts vertex indices)."""
    return orient_ccw(mesh.p.T, mesh.t.T)


def run(scene, out_dir="scene", restart=None, progress=None, overwrite: bool = False, verbose=False) -> RunResult:
    """Build a :class:`Simulation` for ``scene`` (a Scene or a TOML path) and run it (see :meth:`Simulation.run`)."""
    return Simulation(scene).run(out_dir=out_dir, restart=restart, progress=progress, overwrite=overwrite,
                                 verbose=verbose)
