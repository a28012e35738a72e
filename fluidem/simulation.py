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
fixed- and moving-mesh flows), which take scene specs, not the scene: :mod:`fluidem.build` takes the
scene apart for them; this module is the loop.  What the loop writes is
:mod:`fluidem.records`, continuing from a checkpoint :mod:`fluidem.restart`, stopping on a signal
:mod:`fluidem.signals`, the verbose per-step lines :mod:`fluidem.progress`; :class:`RunStopped` and
:class:`RunWarning` are :mod:`fluidem.errors`' (all importable from here as well).  Free bodies in a fluid need the
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

from . import build
from . import restart as restart_
from .coupling.bodies import KinematicBodies  # noqa: F401 (importable from here, as before)
from .coupling.bodies import DEMBodies, FlowBodies, LinearPath
from .cost import CostSplit
from .diagnostics import RunDiagnostics
from .errors import InputError, RunStopped, RunWarning
from .progress import VerboseProgress, step_info, verbose_line
from .records import TRANSIENT_FAILURES  # noqa: F401 (importable from here, as before the split)
from .records import (_ccw, check_owner, close_complete, close_stopped, log_mesh_event, log_unresolved_approach,
                      open_output, record_step)
from .records import summary as run_summary
from .restart import RESTART_MAY_CHANGE, scene_changes
from .restart import scene_key  # noqa: F401 (importable from here, as before the split)
from .scene import Scene
from .signals import SignalGuard
from .state_checks import StateCheck, StateError
from .validate import integer

__all__ = ["Simulation", "RunResult", "StepTimes", "run", "LinearPath", "RunStopped", "RunWarning", "StateError",
           "scene_changes", "RESTART_MAY_CHANGE", "verbose_line"]

#: a snapshot of the state (to checkpoint if a later step fails) is taken once the steps since the
#: last one took this many times the snapshot's own time: every step for fluid runs, every few
#: steps for cheap DEM steps of many bodies
SNAPSHOT_RATIO = 20.0

#: smallest triangle angle (degrees) of a freshly built mesh before a warning
MIN_ANGLE = 5.0

#: Former name of the per-step cost record (now :class:`fluidem.cost.CostSplit`; parts read as attributes).
StepTimes = CostSplit


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
        self.bodies = build.bodies_of(scene, self.plan.on("contacts"))
        if isinstance(self.bodies, DEMBodies):
            self.counters["dem"] += 1
        if scene.fluid is not None:
            with self.diagnostics.watching():  # an LU of the set-up (Stokes mobility) goes into step 1's record
                if isinstance(self.bodies, FlowBodies):
                    self.flow = self.bodies.flow = build.free_body_flow(scene, self)
                elif self.plan.mesh == "moving":
                    self.flow = build.moving_mesh_flow(scene, self)
                else:
                    self.flow = build.fixed_mesh_flow(scene, self)
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

        The checks, what the scene may change and the errors are those of
        :func:`fluidem.restart.restore`.  Returns the checkpoint used.
        """
        return restart_.restore(self, checkpoint, allow_pickle=allow_pickle)

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
            Steps, time, ``wall_s`` (if given: wall seconds of the stepping loop), mesh size and each
            body's final state and last load (:func:`fluidem.records.summary` lists them with units).
        """
        return run_summary(self, wall_s)

    def _health(self, writer, ev_mesh) -> None:
        """Close the step's health record (:class:`fluidem.diagnostics.RunDiagnostics`); a threshold
        crossed is a :class:`RunWarning` and a ``health`` line in events.log."""
        d = self.diagnostics
        d.finish_step(self.step_index, self.t, ev_mesh, getattr(self.flow, "mm", None),
                      getattr(self.flow, "problem", None))
        for w in d.check():
            if writer is not None:
                writer.event(self.step_index, self.t, "health", w)
            warnings.warn(w, RunWarning, stacklevel=6)  # at the caller of run()

    # -- per-step report -------------------------------------------------------------------------
    def step_info(self) -> dict:
        """What the last step's solvers recorded, for a verbose progress line.

        Returns
        -------
        dict
            Step, time, the last linear solve, CFL number, contacts, health
            (:func:`fluidem.progress.step_info` lists the keys).
        """
        return step_info(self)

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
            progress = VerboseProgress(self, stream, progress)
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
            from .io.xdmf import require_h5py  # before anything is written, the folder included

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
        """:meth:`run` with its arguments checked, holding the output directory's lock: restore the
        checkpoint (a restart), open the output, step (:meth:`_steps`), close the output as complete or
        stopped (:func:`fluidem.records.close_complete`, :func:`fluidem.records.close_stopped`)."""
        restarting = restart is not None and restart is not False
        ck_used, n_events = None, len(self.events)
        if restarting:
            ck_used = self.restore(restart, allow_pickle=allow_pickle)  # lists any change of the scene
            if out_dir is not None and Path(out_dir).is_dir() and \
                    Path(out_dir).resolve() not in Path(ck_used).resolve().parents:
                check_owner(self, out_dir)  # a checkpoint from elsewhere: the folder must be this scene's
        N = self.plan.n_steps if n_steps is None else n_steps
        writer = None
        if out_dir is not None:
            mode = "restart" if restarting else ("overwrite" if overwrite else "new")
            writer = open_output(self, out_dir, mode, N, ck_used, n_events)
        loop = _Loop.start(self.scene, N)
        self._steps(writer, loop, progress)
        if writer is not None and loop.stop is None:
            close_complete(self, writer, out_dir, N, loop.last_ck, loop.totals, loop.wall0)
        elif writer is not None:
            close_stopped(self, writer, out_dir, N, loop.stop, loop.snap, loop.keep, loop.totals, loop.wall0)
        if isinstance(self.bodies, DEMBodies):
            self.counters["dem_substeps"] = self.bodies.substeps
        elif getattr(self.flow, "contacts", None) is not None:
            self.counters["dem_substeps"] = self.flow.contacts.substeps
        return RunResult(self.step_index, self.t, None if out_dir is None else str(out_dir),
                         time.perf_counter() - loop.wall0, self.flow.dofs if self.flow else 0, loop.totals,
                         ("curved" if self.flow.curved else "polygonal") if self.flow else "")

    def _steps(self, writer, loop: _Loop, progress) -> None:
        """Step to ``loop.n_steps`` under a :class:`~fluidem.signals.SignalGuard`.

        With output, a signal, an error inside a step (the state is then the failed step's) or one
        while recording it sets ``loop.stop`` and ends the loop; after a signal between steps the
        state now is snapshotted (it is good).  Without output (``writer`` None) the error itself
        propagates, and a signal as ``KeyboardInterrupt``.
        """
        guard = SignalGuard()
        try:
            with guard:
                if self.step_index == 0 and writer is not None:
                    record_step(self, writer, fields=True)
                if writer is not None:
                    loop.snap = self._snapshot()
                while self.step_index < loop.n_steps:
                    if guard.signal:
                        loop.stop = ("interrupt", guard.signal, None)
                        break
                    t_step = time.perf_counter()
                    try:
                        st = self._advance(loop.dt, writer, loop.check)
                    except KeyboardInterrupt:
                        if writer is None:
                            raise
                        loop.stop = ("interrupt", "SIGINT", None)
                        break
                    except Exception as exc:
                        if writer is None:
                            raise
                        self._failed = True  # the state is the failed step's; the last good one is recorded
                        loop.stop = ("error", None, exc, self.step_index + 1)
                        break
                    self._after_step(writer, loop, st, t_step, progress)
            if guard.signal and loop.stop is None and self.step_index < loop.n_steps:
                loop.stop = ("interrupt", guard.signal, None)
            if (loop.stop is not None and loop.stop[0] == "interrupt" and writer is not None
                    and loop.snap[0] != self.step_index):
                loop.snap = self._snapshot()  # stopped between steps: the state now is good
            if loop.stop is not None and writer is None:
                raise KeyboardInterrupt
        except BaseException as exc:  # outside a step (recording, output, progress)
            if writer is None or isinstance(exc, (SystemExit, GeneratorExit)):
                if writer is not None:
                    writer.close()
                raise
            loop.stop = ("interrupt", "SIGINT", None) if isinstance(exc, KeyboardInterrupt) else \
                ("error", None, exc, max(self.step_index, 1))  # recording the step failed

    def _after_step(self, writer, loop: _Loop, st: CostSplit, t_step: float, progress) -> None:
        """Count the step just taken (``t_step`` its start on the wall clock), record it (loads, history,
        fields at output steps, health, mesh events and quality), checkpoint it when due, add its cost
        ``st`` to the run's and report progress."""
        self.step_index += 1
        self.counters["steps"] += 1
        self.t = self.step_index * loop.dt
        t0 = time.perf_counter()
        last = self.step_index == loop.n_steps
        output_step = self.step_index % loop.every == 0 or last
        t_loads = record_step(self, writer, fields=output_step, last=last)
        ev_mesh = getattr(self.flow, "last_event", None) if self.flow is not None else None
        if self.flow is not None:
            self._health(writer, ev_mesh)
        if ev_mesh is not None and writer is not None:  # after the loads: the force change is known
            log_mesh_event(self, writer, ev_mesh)
        log_unresolved_approach(self, writer)
        if writer is not None and self.plan.mesh == "moving" and output_step:
            writer.mesh_quality(self.step_index, self.t, self.flow.mm.quality())
        if writer is not None:
            self._checkpoint_if_due(writer, loop, t_step, last)
        st.add("loads", t_loads)
        st.add("output", time.perf_counter() - t0 - t_loads)
        st.count("steps")
        loop.totals += st
        if progress is not None:
            progress(self.step_index, loop.n_steps, self.t, st)

    def _checkpoint_if_due(self, writer, loop: _Loop, t_step: float, last: bool) -> None:
        """A snapshot of the state when due (:data:`SNAPSHOT_RATIO`), and a checkpoint of it at the
        cadence in steps or wall seconds and at the last step."""
        now = time.perf_counter()
        loop.since += now - t_step
        due = (loop.ck and self.step_index % loop.ck == 0) or last or \
            (loop.ck_wall and now - loop.last_ck_wall >= loop.ck_wall)
        if due or loop.since >= SNAPSHOT_RATIO * loop.snap_s:  # snapshots cost at most ~5 % of the steps
            loop.snap = self._snapshot()
            loop.snap_s, loop.since = time.perf_counter() - now, 0.0
        if due:
            loop.last_ck = writer.checkpoint(self.step_index, self.t, header=self._header(), snapshot=loop.snap[2],
                                             keep=loop.keep)
            loop.last_ck_wall = now


@dataclass
class _Loop:
    """The cadence and the running state of one run's stepping loop (:meth:`Simulation._steps`)."""

    n_steps: int
    dt: float
    every: int  # fields (and the moving mesh's quality) every this many steps
    ck: int | None  # a checkpoint every this many steps
    ck_wall: float | None  # ... and every this many wall-clock seconds
    keep: int | None  # checkpoints kept (None: all)
    check: StateCheck
    totals: CostSplit = field(default_factory=CostSplit)
    wall0: float = 0.0  # perf_counter() at the start of the steps
    last_ck_wall: float = 0.0
    stop: tuple | None = None  # ("interrupt", signal name, None) or ("error", None, exception, failed step)
    snap: tuple | None = None  # the last snapshot: (step, t, (tree, arrays))
    snap_s: float = 0.0  # seconds the last snapshot took
    since: float = 0.0  # seconds of the steps since
    last_ck: Path | None = None  # the last checkpoint written

    @classmethod
    def start(cls, sc: Scene, n_steps: int) -> _Loop:
        """The loop of a run of scene ``sc`` to step ``n_steps``, its wall clock started."""
        ck, keep = sc.output.checkpoint_every, None
        if ck is None:  # the default cadence: about ten checkpoints a run, the newest three kept
            ck, keep = max(1, -(-n_steps // 10)), 3
        loop = cls(n_steps, sc.time.dt, sc.output.every, ck, sc.output.checkpoint_seconds, keep,
                   StateCheck.for_scene(sc))
        loop.wall0 = loop.last_ck_wall = time.perf_counter()
        return loop


def run(scene, out_dir="scene", restart=None, progress=None, overwrite: bool = False, verbose=False) -> RunResult:
    """Build a :class:`Simulation` for ``scene`` (a Scene or a TOML path) and run it (see :meth:`Simulation.run`)."""
    return Simulation(scene).run(out_dir=out_dir, restart=restart, progress=progress, overwrite=overwrite,
                                 verbose=verbose)
