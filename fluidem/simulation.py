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
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .coupling.bodies import DEMBodies, KinematicBodies, LinearPath
from .cost import CostSplit
from .geometry import orient_ccw
from .scene import Scene

__all__ = ["Simulation", "RunResult", "StepTimes", "run", "LinearPath"]

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
    scene : Scene or str or Path
        A scene or the path of a TOML scene file.

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
        A scene this version cannot run (free bodies in a fluid, translating bodies in an
        unsteady fluid, periodic sides), with the reason.

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
        if not isinstance(scene, Scene):
            scene = Scene.from_toml(scene)
        self.scene = scene
        self.plan = scene.plan()
        if self.plan.unsupported:
            raise ValueError("this scene cannot run yet: " + "; ".join(self.plan.unsupported))
        self.counters = {"triangulations": 0, "fluid_solvers": 0, "dem": 0, "steps": 0, "dem_substeps": 0}
        self.step_index = 0
        self.t = 0.0
        self.flow = None
        self.events = [("built", f"plan: mesh {self.plan.mesh}, contacts {self.plan.on('contacts')}")]
        if self.plan.on("contacts") and scene.fluid is None:
            self.bodies = DEMBodies(scene)
            self.counters["dem"] += 1
        else:
            self.bodies = KinematicBodies(scene)
        if scene.fluid is not None:
            if self.plan.mesh == "moving":
                from .coupling.moving_flow import MovingMeshFlow

                self.flow = MovingMeshFlow(scene, self)
            else:
                from .coupling.fixed_flow import FixedMeshFlow

                self.flow = FixedMeshFlow(scene, self)
            self.events.append(("mesh", ("moving, initial: " if self.plan.mesh == "moving" else "built once: ")
                                + f"{self.flow.mesh.t.shape[1]} triangles, "
                                        f"{self.flow.dofs} DOFs, {'curved' if self.flow.curved else 'polygonal'}"))

    # -- state ------------------------------------------------------------------------------
    def _state(self) -> dict:
        return {"bodies": self.bodies.get_state(), "flow": self.flow.get_state() if self.flow else None,
                "scene": self.scene.to_dict(), "counters": dict(self.counters)}

    def restore(self, checkpoint) -> None:
        """Continue from a checkpoint file or output directory (its newest checkpoint)."""
        from .io import load_checkpoint

        data = load_checkpoint(checkpoint)
        if data["scene"] != self.scene.to_dict():
            diff = [k for k in data["scene"] if data["scene"][k] != self.scene.to_dict().get(k)]
            allowed = {"time", "output"}
            if set(diff) - allowed:
                raise ValueError(f"checkpoint {str(checkpoint)!r} belongs to a different scene (tables differ: "
                                 f"{', '.join(sorted(set(diff) - allowed))}); allowed changes: time.t_end, output")
        self.bodies.set_state(data["bodies"])
        if self.flow is not None:
            self.flow.set_state(data["flow"])
        self.step_index = int(data["step"])
        self.t = float(data["t"])

    def _record(self, writer, fields: bool, last: bool = False):
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
        if self.step_index % sc.output.history_every == 0 or last:
            writer.history(self.step_index, self.t, b.positions, b.angles, b.velocities, b.omegas, F, T, cnt)
        if fields:
            pos, ang = b.positions, b.angles
            outlines = [sb.world_vertices(sc.default_segments(sb), pos[k], ang[k]) for k, sb in enumerate(sc.bodies)]
            if outlines:
                writer.bodies(self.step_index, self.t, outlines, b.velocities, b.omegas)
            if self.flow is not None and sc.output.fields:
                from .io import fluid_point_data

                m = self.flow.mesh
                writer.fields(self.step_index, self.t, m.p[:, :m.nvertices].T, _ccw(m),
                              fluid_point_data(self.flow.space, self.flow.x))
        return t_loads

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
        if len(ev_mesh.oscillating):
            writer.event(self.step_index, self.t, "oscillation", f"{len(ev_mesh.oscillating)} oscillating nodes")

    # -- running ---------------------------------------------------------------------------------
    def run(self, out_dir="scene", restart=None, progress=None, n_steps: int | None = None) -> RunResult:
        """Step to ``time.t_end`` (or ``n_steps`` steps in total), writing output to ``out_dir``.

        Parameters
        ----------
        out_dir : str, Path or None
            Output directory; ``"scene"`` takes ``[output] dir``; ``None`` writes nothing.
        restart : str, Path or True, optional
            Continue from a checkpoint file, or from the newest checkpoint in ``out_dir``
            (``True``); the history is cut back to the checkpoint and continued.
        progress : callable, optional
            ``progress(step, n_steps, t, cost)`` after every step, ``cost`` the step's
            :class:`~fluidem.cost.CostSplit`.
        n_steps : int, optional
            Stop after this many steps in total (the plan's ``round(t_end/dt)`` by default).
        """
        from .io import OutputWriter

        sc = self.scene
        if out_dir == "scene":
            out_dir = sc.output.dir
        if restart is not None and restart is not False:
            if restart is True:
                if out_dir is None:
                    raise ValueError("restart = True needs an output directory with checkpoints")
                restart = out_dir
            self.restore(restart)
        writer = None
        if out_dir is not None:
            writer = OutputWriter(out_dir, restart_step=self.step_index if restart else None)
            if not restart:
                sc.to_toml(Path(out_dir) / "scene.toml")
                for kind, msg in self.events:
                    writer.event(0, 0.0, kind, msg)
                if self.flow is not None:
                    from .mesh.quality import mesh_quality

                    m = self.flow.mesh
                    writer.mesh_quality(0, 0.0, mesh_quality(m.p[:, :m.nvertices].T, _ccw(m)))
            else:
                writer.event(self.step_index, self.t, "restart", f"from {restart}")
        N = self.plan.n_steps if n_steps is None else int(n_steps)
        dt = sc.time.dt
        ev, ck = sc.output.every, sc.output.checkpoint_every
        totals = CostSplit()
        wall0 = time.perf_counter()
        try:
            if self.step_index == 0 and writer is not None:
                self._record(writer, fields=True)
            while self.step_index < N:
                st = CostSplit()
                with st.timer("bodies"):
                    self.bodies.step(dt)
                if self.flow is not None:
                    self.flow.step(dt)
                    st += self.flow.last_cost
                ev_mesh = getattr(self.flow, "last_event", None) if self.flow is not None else None
                self.step_index += 1
                self.counters["steps"] += 1
                self.t = self.step_index * dt
                t0 = time.perf_counter()
                last = self.step_index == N
                t_loads = self._record(writer, fields=(self.step_index % ev == 0 or last), last=last)
                if ev_mesh is not None and writer is not None:  # after the loads: the force change is known
                    self._log_mesh_event(writer, ev_mesh)
                if writer is not None and self.plan.mesh == "moving" and (self.step_index % ev == 0 or last):
                    writer.mesh_quality(self.step_index, self.t, self.flow.mm.quality())
                if writer is not None and ((ck and self.step_index % ck == 0) or last):
                    writer.checkpoint(self.step_index, self.t, self._state())
                st.add("loads", t_loads)
                st.add("output", time.perf_counter() - t0 - t_loads)
                st.count("steps")
                totals += st
                if progress is not None:
                    progress(self.step_index, N, self.t, st)
        finally:
            if writer is not None:
                writer.event(self.step_index, self.t, "end", f"{self.counters['steps']} steps this run")
                writer.close()
        if isinstance(self.bodies, DEMBodies):
            self.counters["dem_substeps"] = self.bodies.substeps
        return RunResult(self.step_index, self.t, None if out_dir is None else str(out_dir),
                         time.perf_counter() - wall0, self.flow.dofs if self.flow else 0, totals,
                         ("curved" if self.flow.curved else "polygonal") if self.flow else "")


def _ccw(mesh) -> np.ndarray:
    """Triangles (m, 3) of a scikit-fem mesh, counter-clockwise (scikit-fem sorts vertex indices)."""
    return orient_ccw(mesh.p.T, mesh.t.T)


def run(scene, out_dir="scene", restart=None, progress=None) -> RunResult:
    """Build a :class:`Simulation` for ``scene`` (a Scene or a TOML path) and run it."""
    return Simulation(scene).run(out_dir=out_dir, restart=restart, progress=progress)
