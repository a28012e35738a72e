"""Restarts: what a restart may change of a scene, and a run's state set from a checkpoint.

* :func:`scene_changes` lists the changes between two scene dicts a restart does not allow
  (anything but ``time.t_end``, ``[output]``, ``name`` and ``description``); :func:`scene_key` is
  a digest of the rest, which ``run.json`` records so an output directory is continued only by
  its own scene;
* :func:`restore` (behind :meth:`fluidem.simulation.Simulation.restore`) continues a
  :class:`~fluidem.simulation.Simulation` from a checkpoint file or the newest valid checkpoint
  of an output directory, each checked against the scene (:func:`apply_checkpoint`) before the
  run goes on.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .build import dem_from_kinematic
from .coupling.bodies import DEMBodies, KinematicBodies
from .errors import InputError, RunWarning, one_line

__all__ = ["RESTART_MAY_CHANGE", "SCENE_RTOL", "ADDED_KEYS", "changes_text", "scene_changes", "scene_key",
           "restore", "apply_checkpoint", "set_state",
           "check_restored"]

#: parts of a run's state whose sizes change as it goes (contact lists, spring histories, neighbour pairs)
_VARIABLE_STATE = (".contacts", "._hist.", "._nbr[", "_pairs", ".springs")

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


#: relative difference below which two numbers of a scene count as equal (relative to the largest
#: magnitude of their list, for outlines): a run's ``scene.toml`` read back differs from the run's own
#: scene in the last digits of its polygon outlines (shifted again onto their area centroid, computed
#: to about 1e-12 of the outline's size where the vertices were given far from the origin), which must
#: not refuse a restart from that file
SCENE_RTOL = 1e-10


def _numbers(v):
    """The numbers of a (nested) list of numbers as a float array, else None."""
    if isinstance(v, (bool, np.bool_, str)) or v is None or isinstance(v, dict):
        return None
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        return None
    return a if a.dtype == float and a.size else None


def _same_value(a, b) -> bool:
    """``a == b``, numbers (and lists of numbers of one shape) within :data:`SCENE_RTOL` of the largest
    magnitude among them."""
    if type(a) is type(b) and a == b:
        return True
    x, y = _numbers(a), _numbers(b)
    if x is None or y is None or x.shape != y.shape:
        return False
    fin = np.isfinite(x)
    if not (np.array_equal(fin, np.isfinite(y)) and np.array_equal(x[~fin], y[~fin], equal_nan=True)):
        return False
    scale = float(np.abs(np.concatenate([x[fin], y[fin]])).max(initial=0.0))
    return bool(np.all(np.abs(x[fin] - y[fin]) <= SCENE_RTOL * scale))


#: scene keys added after runs had been written, with the value an older scene (without the key)
#: ran with: such a key at that value is left out of :func:`scene_changes` and :func:`scene_key`, so
#: the checkpoints and output directories of earlier versions continue
ADDED_KEYS = {"mesh.repair": False}


def _fixed(flat: dict) -> dict:
    return {k: v for k, v in flat.items() if k not in RESTART_MAY_CHANGE and k != "output" and
            not k.startswith("output.") and not (k in ADDED_KEYS and v == ADDED_KEYS[k])}


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
            for k in keys if not _same_value(a.get(k, missing), b.get(k, missing))]


def changes_text(changes: list, shown: int = 3, width: int = 300) -> str:
    """The first ``shown`` of :func:`scene_changes`, each cut to ``width`` characters, and how many more.

    Examples
    --------
    >>> changes_text(["a 1 -> 2", "b 1 -> 3", "c 0 -> 1", "d 0 -> 2"], shown=2)
    'a 1 -> 2; b 1 -> 3; and 2 more'
    """
    cut = [c if len(c) <= width else c[: width - 5] + " ..." for c in changes[:shown]]
    more = len(changes) - len(cut)
    return "; ".join(cut + ([f"and {more} more"] if more > 0 else []))


def scene_key(d: dict) -> str:
    """A digest of what a restart must keep of a scene dict (see :func:`scene_changes`)."""
    import hashlib
    import json

    flat = _fixed(_flatten(d))
    return hashlib.sha256(json.dumps(flat, sort_keys=True, default=str).encode()).hexdigest()[:16]


def restore(sim, checkpoint, allow_pickle: bool = False) -> Path:
    """Continue from a checkpoint file, or from the newest valid checkpoint of an output directory.

    What the checkpoint holds is checked against the scene before the run continues: each
    part must be of the kind and fluidem class a fresh state of this scene has, the arrays
    of the bodies must have their shapes (:func:`fluidem.checkpoint.mismatches`), and the
    restored bodies and flow must be finite and of the scene's sizes.  In a directory a
    checkpoint that fails (damaged, crafted or edited) is skipped with a
    :class:`~fluidem.errors.RunWarning` and the previous one is used.  The scene may differ from the
    checkpoint's only in ``time.t_end``, ``[output]``, its name and description; when the
    longer ``t_end`` switches contacts on, the DEM continues the closed-form motion.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
        The simulation to continue, as built from its scene (nothing stepped yet).
    checkpoint : str or Path
        A checkpoint file, or an output directory whose newest valid checkpoint is used.
    allow_pickle : bool
        Accept a pickle checkpoint of an earlier version (only for your own files).

    Returns
    -------
    Path
        The checkpoint used.

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
    template = {"bodies": sim.bodies.get_state(), "flow": sim.flow.get_state() if sim.flow else None}
    if not path.is_dir():
        apply_checkpoint(sim, path, load_checkpoint(path, allow_pickle=allow_pickle), template)
        return path
    files = checkpoint_files(path) or [latest_checkpoint(path)]
    bodies, counters = sim.bodies, dict(sim.counters)
    skipped = []
    for f in files:
        try:
            apply_checkpoint(sim, f, load_checkpoint(f), template)
        except CheckpointError as exc:
            skipped.append(str(exc))
            sim.bodies, sim.counters = bodies, dict(counters)  # the next one applies to the scene's own
            continue
        for why in skipped:
            warnings.warn(f"{why}; continuing from the previous valid checkpoint {str(f)!r}", RunWarning,
                          stacklevel=4)
        return f
    raise CheckpointError(f"no valid checkpoint in {str(path / 'checkpoints')!r}: " + "; ".join(skipped))


def apply_checkpoint(sim, path: Path, data: dict, template: dict) -> None:
    """Set the run's state from a loaded checkpoint of this scene, checked against ``template``.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
        The simulation whose state is set (bodies, flow, step, time and last loads).
    path : Path
        Where the checkpoint was read, for the messages.
    data : dict
        The loaded checkpoint (:func:`fluidem.io.load_checkpoint`).
    template : dict
        The fresh state of the scene (``bodies`` and ``flow``) the checkpoint's parts must match
        (see :func:`restore`).

    Raises
    ------
    fluidem.errors.InputError
        A different scene, a checkpoint beyond ``t_end`` or one of another kind of flow.
    fluidem.checkpoint.CheckpointError
        A checkpoint without a valid step and time, or whose state does not fit the scene.
    """
    from .checkpoint import CheckpointError, mismatches

    sc = sim.scene
    changes = scene_changes(data.get("scene") or {}, sc.to_dict())
    if changes:
        raise InputError(f"checkpoint {str(path)!r} belongs to a different scene: changed "
                         + changes_text(changes) + "; a restart may change only time.t_end and [output] (anything "
                         "else is a new run: --overwrite or another --out)")
    try:
        step, t = int(data["step"]), float(data["t"])
    except (KeyError, TypeError, ValueError):
        raise CheckpointError(f"checkpoint {str(path)!r} has no valid step and time") from None
    if step > sim.plan.n_steps:
        raise InputError(f"time.t_end = {sc.time.t_end:g}: the checkpoint {str(path)!r} is at t = {t:g} (step "
                         f"{step}); expected a t_end of at least {t:g}")
    flow_kind = type(sim.flow).__name__ if sim.flow is not None else None
    old = data.get("plan") or {}
    if old.get("flow", flow_kind) != flow_kind:
        raise InputError(f"time.t_end = {sc.time.t_end:g}: the longer run needs a {sim.plan.mesh!r} mesh, the "
                         f"checkpoint {str(path)!r} holds a {old.get('mesh')!r} one; run the longer scene from the "
                         "start (--overwrite)")
    n, n_free = len(sc.bodies), sum(b.motion == "free" for b in sc.bodies)

    def per_body(at, shape):  # arrays of the bodies keep their shape; contact lists vary
        return (at.startswith(("state.bodies.", "state.flow.bodies.")) or at.endswith(".mm.poses")) and \
            (n in shape or n_free in shape) and not any(v in at for v in _VARIABLE_STATE)

    state = {k: data.get(k) for k in ("bodies", "flow")}
    if isinstance(sim.bodies, DEMBodies) != ("dem" in (state["bodies"] or {})):
        template = {**template, "bodies": None}  # a longer t_end switched contacts on (or off): converted below
    bad = mismatches(state, template, exact_shape=per_body)
    if bad:
        raise CheckpointError(f"checkpoint {str(path)!r} does not fit the scene: " + "; ".join(bad))
    try:
        set_state(sim, state["bodies"], state["flow"], step)
        check_restored(sim)
    except CheckpointError as exc:
        raise CheckpointError(f"checkpoint {str(path)!r} does not fit the scene: {exc}") from None
    except Exception as exc:  # a part that decodes but does not fit where it goes
        raise CheckpointError(f"checkpoint {str(path)!r} does not fit the scene ({type(exc).__name__}: "
                              f"{one_line(exc)[:120]})") from None
    sim.step_index = step
    sim.t = t
    loads = data.get("loads")
    if loads is not None:
        sim.last_loads = (np.asarray(loads[0], float), np.asarray(loads[1], float))


def set_state(sim, bs: dict, flow_state, step: int) -> None:
    """Set the bodies and the flow of ``sim`` from decoded state (a checkpoint's or a snapshot's).

    A closed-form (kinematic) state goes into a DEM when the scene's plan has contacts on from
    ``step`` (an event says so), and a DEM state replaces closed-form bodies.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
    bs : dict
        The bodies' state (``get_state`` of the bodies adapter).
    flow_state : dict or None
        The flow's state (None for a dry scene).
    step : int
        The step the state is of.
    """
    sc = sim.scene
    if isinstance(sim.bodies, DEMBodies) and "dem" not in bs:
        kin = KinematicBodies(sc.bodies, sc.gravity)
        kin.set_state(bs)
        sim.bodies = dem_from_kinematic(sc, kin)
        sim.events.append(("plan", f"from step {step} contacts are on: the DEM continues the closed-form motion"))
    elif isinstance(sim.bodies, KinematicBodies) and "dem" in bs:
        dem = DEMBodies.__new__(DEMBodies)
        dem.n = len(sc.bodies)
        dem.set_state(bs)
        sim.bodies = dem
    else:
        sim.bodies.set_state(bs)
    if sim.flow is not None:
        sim.flow.set_state(flow_state)


def check_restored(sim) -> None:
    """The restored bodies and flow of ``sim`` have the scene's sizes and finite values.

    Raises
    ------
    fluidem.checkpoint.CheckpointError
        The part that does not (positions, angles, velocities, omegas or flow), its shape and
        whether its values are finite.
    """
    from .checkpoint import CheckpointError

    n, b = len(sim.scene.bodies), sim.bodies
    parts = [("positions", b.positions, (n, 2)), ("angles", b.angles, (n,)),
             ("velocities", b.velocities, (n, 2)), ("omegas", b.omegas, (n,))]
    if sim.flow is not None:
        parts.append(("flow", sim.flow.x, (int(sim.flow.dofs),)))
    for name, a, shape in parts:
        a = np.asarray(a)
        if a.shape != shape or a.dtype.kind != "f" or not np.isfinite(a).all():
            raise CheckpointError(f"{name} of shape {a.shape}" + ("" if a.shape != shape or a.dtype.kind != "f"
                                                                  else " with non-finite values")
                                  + f" (expected finite numbers of shape {shape})")
