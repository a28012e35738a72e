"""What a run writes: history rows, side loads, field series, events, checkpoints at its end, run.json.

The files are :mod:`fluidem.io`'s; this module says what goes into them, and when, as the loop of
:class:`fluidem.simulation.Simulation` runs:

* :func:`open_output` prepares the output directory (:func:`fluidem.io.prepare_output_dir`),
  writes ``scene.toml``, the first events and the mesh quality, and ``run.json`` with status
  ``running`` (:func:`run_record`);
* after each step :func:`record_step` takes the loads and writes the history rows, the loads on
  the box's sides (:func:`record_sides`) and, at output steps, the fields (:func:`write_fields`);
  :func:`log_mesh_event` says in events.log what the moving mesh did;
* a run that reaches its end is closed by :func:`close_complete` (the XDMF series if asked, the
  last events, ``run.json`` with its cost and summary); one that stops early by
  :func:`close_stopped`: the fields and the checkpoint of the last good step, a message that says
  where and how to continue, and :class:`~fluidem.errors.RunStopped`.
"""

from __future__ import annotations

import time
import warnings
from contextlib import nullcontext
from pathlib import Path

import numpy as np

from .cost import CostSplit
from .diagnostics import oscillation_text
from .errors import RunStopped, RunWarning, one_line
from .geometry import orient_ccw, wrap_into_box
from .restart import scene_key, set_state
from .state_checks import StateError

__all__ = ["TRANSIENT_FAILURES", "open_output", "record_step", "record_sides", "write_fields", "log_mesh_event",
           "summary", "run_record", "rheology_record", "check_owner", "close_complete", "close_stopped",
           "last_good_fields"]

#: Failures a restart from the last checkpoint can get past: they come from the machine (a full disk,
#: an unwritable folder, memory), not from the scene and its state, which a restart replays exactly.
TRANSIENT_FAILURES = (OSError, MemoryError)


def _ccw(mesh) -> np.ndarray:
    """Triangles (m, 3) of a scikit-fem mesh, counter-clockwise (scikit-fem sorts vertex indices)."""
    return orient_ccw(mesh.p.T, mesh.t.T)


def open_output(sim, out_dir, mode: str, n_steps: int, checkpoint=None, n_events: int = 0):
    """Prepare ``out_dir`` for the run of ``sim`` and start its output.

    Writes ``scene.toml`` (the scene as run: on a restart with its new ``t_end``), the events so
    far (a fresh run: those of the build and the mesh quality at step 0; a restart: where it
    restarts from and the events since ``n_events``) and ``run.json`` with status ``running``.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
    out_dir : str or Path
        The output directory.
    mode : {"new", "overwrite", "restart"}
        How to treat run output already there (:func:`fluidem.io.prepare_output_dir`).
    n_steps : int
        The steps this run goes to.
    checkpoint : Path, optional
        The checkpoint a restart continues from.
    n_events : int
        On a restart, the events of ``sim`` from before the checkpoint was restored (not written again).

    Returns
    -------
    fluidem.io.OutputWriter
    """
    from .io import OutputWriter, prepare_output_dir

    sc = sim.scene
    restarting = mode == "restart"
    prepare_output_dir(out_dir, mode)
    writer = OutputWriter(out_dir, restart_step=sim.step_index if restarting else None)
    sc.to_toml(Path(out_dir) / "scene.toml")  # the scene as run (on a restart: with its new t_end)
    if not restarting:
        for kind, msg in sim.events:
            writer.event(0, 0.0, kind, msg)
        if sim.flow is not None:
            from .mesh.quality import mesh_quality

            m = sim.flow.mesh
            writer.mesh_quality(0, 0.0, mesh_quality(m.p[:, :m.nvertices].T, _ccw(m)))
    else:
        writer.event(sim.step_index, sim.t, "restart", f"from {checkpoint}")
        for kind, msg in sim.events[n_events:]:
            writer.event(sim.step_index, sim.t, kind, msg)
    run_record(sim, out_dir, "running", n_steps)
    return writer


def record_step(sim, writer, fields: bool, last: bool = False) -> float:
    """Loads of the step just taken; with a writer its history rows and (``fields``) its fields.

    The loads go to ``sim.last_loads``; at history steps (and the ``last``) the rows of
    history.csv and sides.csv are written, and what ``run.json`` reports should a later step
    fail is kept (this step, the last good one).

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
        After a step (or at step 0).
    writer : fluidem.io.OutputWriter or None
        None: the loads only.
    fields : bool
        Write the body outlines and the flow fields of this step too.
    last : bool
        The run's last step (its history rows are written whatever the cadence).

    Returns
    -------
    float
        The seconds the loads took (the fluid's and the sides').
    """
    held = getattr(sim.flow, "residual_held", None)
    with held() if held is not None else nullcontext():  # one residual for the bodies' loads and the sides'
        return _record_step(sim, writer, fields, last)


def _record_step(sim, writer, fields: bool, last: bool) -> float:
    b = sim.bodies
    F, T, cnt = b.loads()
    tl = time.perf_counter()
    if sim.flow is not None and len(sim.scene.bodies) and sim.step_index > 0:
        F, T = sim.flow.loads()  # at step 0 the flow is only its initial data: no loads
    t_loads = time.perf_counter() - tl
    sim.last_loads = (F, T)
    if writer is None:
        return t_loads
    sc = sim.scene
    pos, ang, vel, om = b.positions, b.angles, b.velocities, b.omegas
    if sim.step_index % sc.output.history_every == 0 or last:
        writer.history(sim.step_index, sim.t, in_box(sim, pos), ang, vel, om, F, T, cnt, unwrapped=pos)
        t_loads += record_sides(sim, writer)
    # what run.json reports if a later step fails: this step, the last good one
    sim._recorded = (sim.step_index, sim.t, pos, ang, vel, om, np.array(F, float), np.array(T, float))
    if fields:
        write_fields(sim, writer)
    return t_loads


def record_sides(sim, writer) -> float:
    """The force of the fluid on every wall, moving wall and inflow side into sides.csv (from step 1:
    at step 0 the flow is only its initial data).

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
    writer : fluidem.io.OutputWriter

    Returns
    -------
    float
        The seconds it took (0 for a dry scene or one without such sides).
    """
    if sim.flow is None or sim.step_index == 0:
        return 0.0
    names = [s for s in ("bottom", "right", "top", "left")
             if sim.scene.domain.side(s).type in ("wall", "moving-wall", "inflow")]
    if not names:
        return 0.0
    from .fluid.forces import side_loads

    t0 = time.perf_counter()
    F = side_loads(sim.flow.space, sim.flow.residual(), names, rho=sim.scene.fluid.density)
    seconds = time.perf_counter() - t0
    writer.sides(sim.step_index, sim.t, names, F)
    return seconds


def in_box(sim, positions) -> np.ndarray:
    """Body positions ``(n, 2)`` wrapped into the box across its periodic sides (the bodies keep
    continuous, unwrapped positions: a body that crossed a side is in the box again here)."""
    from .coupling.boundary import period_of_domain

    return wrap_into_box(positions, sim.scene.domain.box, period_of_domain(sim.scene.domain))


def write_fields(sim, writer) -> None:
    """Body outlines and (fluid scenes, ``output.fields``) the fields of the current state into the series.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
    writer : fluidem.io.OutputWriter
    """
    sc, b = sim.scene, sim.bodies
    pos, ang = in_box(sim, b.positions), b.angles
    outlines = [sb.world_vertices(sc.default_segments(sb), pos[k], ang[k]) for k, sb in enumerate(sc.bodies)]
    if outlines:
        writer.bodies(sim.step_index, sim.t, outlines, b.velocities, b.omegas)
    if sim.flow is not None and sc.output.fields:
        from .io import fluid_point_data, full_order_fields

        m = sim.flow.mesh
        writer.fields(sim.step_index, sim.t, m.p[:, :m.nvertices].T, _ccw(m),
                      fluid_point_data(sim.flow.space, sim.flow.x, sc.fluid.density))
        if sc.output.full_order:
            writer.fields_full(sim.step_index, sim.t,
                               *full_order_fields(sim.flow.space, sim.flow.x, sc.fluid.density))
    sim._fields_step = sim.step_index


def summary(sim, wall_s: float | None = None) -> dict:
    """The run's summary quantities, as ``run.json`` records them at the end of a run.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
    wall_s : float, optional
        Wall seconds of the stepping loop of this run.

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
    rec = getattr(sim, "_recorded", None) if getattr(sim, "_failed", False) else None
    if rec is None:  # the state now (after a failed step: the last step recorded)
        b, n = sim.bodies, len(sim.scene.bodies)
        F, T = getattr(sim, "last_loads", (np.zeros((n, 2)), np.zeros(n)))
        rec = (sim.step_index, sim.t, b.positions, b.angles, b.velocities, b.omegas, F, T)
    step, t, pos, ang, vel, om, F, T = rec
    out = {"steps": step, "t": t}
    if wall_s is not None:
        out["wall_s"] = wall_s
    if sim.flow is not None:
        out.update(dofs=int(sim.flow.dofs), triangles=int(sim.flow.mesh.t.shape[1]),
                   element=sim.scene.fluid.element)
    bodies = {}
    for k, sb in enumerate(sim.scene.bodies):
        name = sb.name or f"body{k}"
        bodies[name] = {"x": float(pos[k, 0]), "y": float(pos[k, 1]), "angle": float(ang[k]),
                        "vx": float(vel[k, 0]), "vy": float(vel[k, 1]), "omega": float(om[k]),
                        "fx": float(F[k, 0]), "fy": float(F[k, 1]), "torque": float(T[k])}
    out["bodies"] = bodies
    return out


def run_record(sim, out_dir, status: str, n_steps: int, checkpoint=None, message: str = "",
               totals: CostSplit | None = None, summary: dict | None = None) -> None:
    """Write ``run.json`` (:func:`fluidem.io.write_run_record`): the scene and its key, how far the run got
    and how it stands, its units; with ``totals`` and ``summary`` its cost and summary quantities.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
    out_dir : str or Path
        The run's output directory.
    status : {"running", "complete", "stopped", "interrupted", "failed"}
    n_steps : int
        The steps this run goes to.
    checkpoint : Path, optional
        The run's last checkpoint (recorded relative to ``out_dir``).
    message : str
        What stopped the run, on one line.
    totals : fluidem.cost.CostSplit, optional
        Seconds per part summed over this run's steps.
    summary : dict, optional
        :meth:`fluidem.simulation.Simulation.summary`.
    """
    from .version import __version__
    from .io import HISTORY_UNITS, write_run_record

    sc, dem = sim.scene, sim.dem_limit()
    write_run_record(out_dir, {
        "format": "fluidem-run-1", "scene": sc.name, "scene_key": scene_key(sc.to_dict()),
        "source": sc.source, "fluidem": __version__, "status": status, "step": sim.step_index, "t": sim.t,
        "n_steps": n_steps, "dt": sc.time.dt, "t_end": sc.time.t_end,
        "checkpoint": None if checkpoint is None else str(Path(checkpoint).relative_to(out_dir)),
        "message": message, "units": HISTORY_UNITS,
        "pressure": "VTU 'pressure' is dynamic (fluid density x kinematic pressure), 'kinematic_pressure' "
                    "beside it; history loads are dynamic too",
        **({} if totals is None else {"cost": {"seconds": dict(totals.parts), "counts": dict(totals.counts),
                                               "note": "wall seconds per part summed over this run's steps"}}),
        **({} if summary is None else {"summary": summary}),
        **({} if dem is None else {"dem_sub_step": dem}),
        **({} if getattr(sim.flow, "ordering", None) is None else
           {"lu_ordering": {**sim.flow.ordering.state(), "note": sim.flow.ordering.summary()}}),
        **({} if getattr(sim.flow, "solver_choice", None) is None else {"linear_solver": sim.flow.solver_choice}),
        **({} if sim.flow is None or not sim.diagnostics.enabled else
           {"diagnostics": sim.diagnostics.record()}),
        **rheology_record(sim, out_dir, status)})


def rheology_record(sim, out_dir, status: str) -> dict:
    """``{"rheology": ...}`` for a complete run of a shear cell (:func:`fluidem.rheology.rheology`
    over its sides.csv, restarts included), else ``{}``.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
    out_dir : str or Path
    status : str
        The run's status (only ``"complete"`` has a rheology).

    Returns
    -------
    dict
    """
    from .rheology import rheology, shear_cell

    if status != "complete" or shear_cell(sim.scene)[0] is None:
        return {}
    from .io import read_sides

    return {"rheology": rheology(sim.scene, read_sides(out_dir))}


def check_owner(sim, out_dir) -> None:
    """Refuse to continue, in ``out_dir``, a run of another scene.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
    out_dir : str or Path

    Raises
    ------
    fluidem.io.OutputDirError
        ``out_dir``'s ``run.json`` has another :func:`fluidem.restart.scene_key`.
    """
    from .io import OutputDirError, read_run_record

    rec = read_run_record(out_dir)
    if rec.get("scene_key") and rec["scene_key"] != scene_key(sim.scene.to_dict()):
        raise OutputDirError(f"output directory {str(out_dir)!r} holds a run of another scene "
                             f"({rec.get('scene')!r}); continue it with its own scene ({str(out_dir)}/scene.toml) "
                             "or give another --out")


def log_mesh_event(sim, writer, ev_mesh) -> None:
    """Event-log lines of this step's mesh update: re-triangulation (reason, where it fired, size, field
    transfer, interpolation noise and force change), a repair of the elements past the angle
    bounds by moving nodes (:mod:`fluidem.mesh.repair`) and oscillating nodes.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
    writer : fluidem.io.OutputWriter
    ev_mesh : object
        The flow's ``last_event``: what the moving mesh did in the step.
    """
    if ev_mesh.retriangulated:
        msg = f"reason={ev_mesh.reason} nodes={ev_mesh.n_nodes} triangles={ev_mesh.n_triangles}"
        if getattr(ev_mesh, "repair_declined", ""):
            msg += f" (not repaired: {ev_mesh.repair_declined})"
        fired = getattr(ev_mesh, "fired_at", ())
        if len(fired):
            x, y = fired[0]
            msg += (f"; {len(fired)} element{'' if len(fired) == 1 else 's'} fired, "
                    f"{'at' if len(fired) == 1 else 'the first at'} ({x:.4g}, {y:.4g})")
        if sim.scene.fluid.model != "stokes":
            how = ("ALE interpolation through the old mesh motion" if ev_mesh.history == "ale" else
                   "interpolation, Eulerian step (old mesh not valid at the new positions)"
                   if ev_mesh.history == "eulerian" else "interpolation")
            msg += f"; fields transferred by {how}"
            if ev_mesh.transfer_change is not None:
                msg += f"; interpolation noise {100 * ev_mesh.transfer_change:.3g} %"
            if ev_mesh.force_change is not None:
                msg += f"; force change {100 * ev_mesh.force_change:.3g} %"
        writer.event(sim.step_index, sim.t, "retriangulation", msg)
        inertial = sim.scene.fluid.model != "stokes"
        if ev_mesh.reason == "seam" and inertial and not sim.__dict__.get("_seam_warned"):
            sim._seam_warned = True
            warnings.warn(f"step {sim.step_index}: a body crosses a straight periodic side (mesh seams 'clip') in "
                          "Navier–Stokes flow: the forces of the steps it crosses carry an ALE error (a disk at Re "
                          "30: up to 1.5 times the drag at U dt = h/5, against 0.28 % with bent sides, seams "
                          "'bend'; docs: moving-mesh, bodies across periodic sides); Stokes flow across the sides "
                          "is accurate", RunWarning, stacklevel=4)
    if getattr(ev_mesh, "n_repaired", 0):
        writer.event(sim.step_index, sim.t, "mesh repair",
                     f"{ev_mesh.n_repaired} node{'' if ev_mesh.n_repaired == 1 else 's'} moved to bring elements past "
                     "the angle bounds or the area floor back within them, no re-triangulation (docs: moving-mesh, "
                     "repair before re-triangulation)")
    if len(ev_mesh.oscillating):
        h = sim.diagnostics.last
        swing = h.swing if h is not None and h.step == sim.step_index else None
        writer.event(sim.step_index, sim.t, "oscillation",
                     oscillation_text(len(ev_mesh.oscillating), len(sim.flow.mm.points), swing))


def log_unresolved_approach(sim, writer) -> None:
    """An ``approach`` line in the event log when the step's prediction put two bodies (or a body and a
    wall) into each other and the solve kept them apart
    (:meth:`fluidem.coupling.free_flow.FreeBodyFlow.predicted_into_each_other`), and a
    :class:`~fluidem.errors.RunWarning` the first time in a run.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
        After a step.
    writer : fluidem.io.OutputWriter or None
        None: the warning only.
    """
    ap = getattr(sim.flow, "unresolved_approach", None) if sim.flow is not None else None
    if ap is None:
        return
    who = (f"body {ap.first!r} and the {ap.second} wall" if ap.wall else
           f"bodies {ap.first!r} and {ap.second!r}")
    msg = (f"{who}, {ap.gap:.3g} apart, were predicted into each other within one step of "
           f"time.dt = {sim.scene.time.dt:g}: the step does not resolve their approach (the mesh follows them "
           "into each other: such a step has kicked a pair through each other); a smaller time.dt shortens the "
           "approach per step")
    if writer is not None:
        writer.event(sim.step_index, sim.t, "approach", msg)
    if not sim.__dict__.get("_approach_warned"):
        sim._approach_warned = True
        warnings.warn(f"step {sim.step_index}: {msg} (docs: free bodies, where a kiss can still fail; every "
                      "such step is an 'approach' line of events.log)", RunWarning, stacklevel=4)


def close_complete(sim, writer, out_dir, n_steps: int, checkpoint, totals: CostSplit, wall0: float) -> None:
    """Close the output of a run that was not stopped: the XDMF time series if the scene asks for
    one (a failure to write it is an event and a :class:`~fluidem.errors.RunWarning`, the run's
    results stand), the ``end`` event, and ``run.json`` with status ``complete`` (``stopped`` when
    it ran fewer steps than its plan) and its cost and summary.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
    writer : fluidem.io.OutputWriter
    out_dir : str or Path
    n_steps : int
        The steps this run went to.
    checkpoint : Path or None
        The run's last checkpoint.
    totals : fluidem.cost.CostSplit
        Seconds per part summed over this run's steps.
    wall0 : float
        ``time.perf_counter()`` at the start of the steps (for the summary's ``wall_s``).
    """
    sc = sim.scene
    if sim.flow is not None and sc.output.fields and sc.output.xdmf:
        from .io import write_xdmf

        try:
            writer.event(sim.step_index, sim.t, "xdmf", str(write_xdmf(out_dir).name))
        except Exception as exc:  # the run's results stand; the series can be written later
            writer.event(sim.step_index, sim.t, "xdmf-failed", one_line(exc))
            warnings.warn(f"the XDMF time series was not written: {one_line(exc)}", RunWarning, stacklevel=3)
    writer.event(sim.step_index, sim.t, "end", f"{sim.counters['steps']} steps this run")
    writer.close()
    run_record(sim, out_dir, "complete" if sim.step_index >= sim.plan.n_steps else "stopped", n_steps,
               checkpoint, totals=totals, summary=sim.summary(time.perf_counter() - wall0))


def close_stopped(sim, writer, out_dir, n_steps, stop, snap, keep, totals, wall0):
    """Close the outputs at the last good step (its fields written, if they were not), checkpoint
    it, record the run's cost and summary, and raise :class:`~fluidem.errors.RunStopped`.

    Parameters
    ----------
    sim, writer, out_dir, n_steps, totals, wall0
        As for :func:`close_complete` (``n_steps``: the steps this run was to go to).
    stop : tuple
        What stopped it: ``("interrupt", signal name, None)`` or ``("error", None, exception,
        failed step)``.
    snap : tuple or None
        The last snapshot of a good state, ``(step, t, (tree, arrays))``.
    keep : int or None
        Checkpoints kept.

    Raises
    ------
    fluidem.errors.RunStopped
        Always: status ``interrupted`` (exit status 130 or 143) or ``failed`` (3), the message
        saying where the last good state is and how to continue; from the error, if one.
    """
    kind, sig, exc = stop[:3]
    step, t, snapshot = snap if snap is not None else (sim.step_index, sim.t, None)
    failed_at = stop[3] if kind == "error" else sim.step_index + 1
    try:
        last_good_fields(sim, writer, snap)
    except Exception as err:  # e.g. the directory is read-only now
        writer.event(step, t, "fields-failed", one_line(err))
    path = None
    try:
        if snapshot is not None:
            path = writer.checkpoint(step, t, header=sim._header(), snapshot=snapshot, keep=keep)
    except Exception as err:  # the disk is full, say: the older checkpoints stay
        writer.event(step, t, "checkpoint-failed", one_line(err))
    sc = sim.scene
    where = f"checkpoint {str(path)!r}" if path is not None else "no new checkpoint (see events.log)"
    how = f"fluidem run {sc.source or str(Path(out_dir) / 'scene.toml')} --out {out_dir} --restart"
    if kind == "interrupt":
        msg = (f"interrupted by {sig} after step {step} of {n_steps} (t = {t:.6g}); the output holds steps 0 to "
               f"{step}; {where}; continue with: {how}")
        status, code = "interrupted", 143 if sig == "SIGTERM" else 130
    else:
        what = one_line(exc)
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
    writer.event(step, t, status, one_line(msg))
    writer.event(step, t, "end", f"{sim.counters['steps']} steps this run")
    writer.close()
    run_record(sim, out_dir, status, n_steps, path, one_line(msg), totals=totals,
               summary=sim.summary(time.perf_counter() - wall0))
    err = RunStopped(msg, status=status, exit_status=code, checkpoint=path)
    if exc is not None:
        raise err from exc
    raise err


def last_good_fields(sim, writer, snap) -> None:
    """Write the fields of the last recorded step if its output step did not (after a failed step:
    from the snapshot, when it is of that step).

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
    writer : fluidem.io.OutputWriter
    snap : tuple or None
        The last snapshot, ``(step, t, (tree, arrays))``.
    """
    if getattr(sim, "_failed", False):
        rec = getattr(sim, "_recorded", None)
        if snap is None or rec is None or snap[0] != rec[0]:
            return
        from .checkpoint import decode

        state = decode(*snap[2])
        set_state(sim, state["bodies"], state["flow"], snap[0])
        sim._failed = False
    if getattr(sim, "_fields_step", None) != sim.step_index:
        write_fields(sim, writer)
