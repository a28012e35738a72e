"""What a run prints as it goes: one plain-text line per step (``fluidem run --verbose``).

:func:`step_info` collects what a step's solvers recorded (behind
:meth:`fluidem.simulation.Simulation.step_info`), :func:`verbose_line` formats it with the step's
cost split, and :class:`VerboseProgress` is the progress callback
:meth:`fluidem.simulation.Simulation.run` installs for ``verbose``.
"""

from __future__ import annotations

from .coupling.bodies import DEMBodies
from .cost import CostSplit

__all__ = ["step_info", "verbose_line", "VerboseProgress"]


def _linear_solver(sim):
    """The linear solver of the last flow step (coupled fluid-body, fluid or Stokes), or None."""
    f = sim.flow
    for owner in (getattr(f, "coupled", None), getattr(f, "stepper", None), f):
        s = getattr(owner, "solver", None)
        if s is not None:
            return s
    return None


def step_info(sim) -> dict:
    """What the last step's solvers recorded, for a verbose progress line.

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
        After a step.

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
    out = {"step": sim.step_index, "t": sim.t}
    if sim.flow is not None:
        s = _linear_solver(sim)
        info = getattr(s, "last_info", None)
        out.update(solver=getattr(info, "method", None), iterations=getattr(info, "iterations", None),
                   residual=getattr(info, "relative_residual", None),
                   factorizations=getattr(s, "factorizations", None))
        st = getattr(sim.flow, "stepper", None)
        out["cfl"] = st._cfl(st.state.u) if st is not None and st.n_steps else None
        h = sim.diagnostics.last
        if h is not None and h.step == sim.step_index and h.text():
            out["health"] = h.text()
    if isinstance(sim.bodies, DEMBodies):
        out["contacts"] = len(sim.bodies.dem.contacts.i)
    contacts = getattr(sim.flow, "contacts", None)
    if contacts is not None and contacts.last_set_by:
        out["dem_set_by"] = contacts.last_set_by
    return out


def verbose_line(info: dict, n_steps: int, cost: CostSplit | None = None) -> str:
    """One line for a step: ``step k/N  t = ...  linear <method> it <n> res <r>  CFL <c>  <health>  <cost split>``
    (``<health>``: ``cond1 <κ₁> (x<growth since the first LU>)`` at a new LU, ``noise <n> %`` at a
    re-triangulation, ``osc <k> nodes``; :mod:`fluidem.diagnostics`);
    with contacts in a fluid also ``DEM <n> sub-steps in <p> passes (<what set the last pass's>), <b> body
    sub-steps`` (the sub-stepped passes over the step, each of at most ``ceil(dt / dt_max)`` sub-steps for
    the group of bodies that takes the most, and the sub-steps summed over the bodies:
    :meth:`fluidem.coupling.contacts.FluidContacts.sub_step_groups`;
    :meth:`fluidem.simulation.Simulation.dem_limit` says what sets ``dt_max``).

    ``info`` as from :func:`step_info`; fields it lacks are left out."""
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
        if cost.counts.get("dem_body_substeps"):  # summed over the bodies (each group at its own sub-steps)
            dem += f", {cost.counts['dem_body_substeps']} body sub-steps"
        if cost.counts.get("contact_unsettled"):
            dem += ", contact load unsettled"
        parts.append(dem)
    if cost is not None and cost.counts.get("approach_unresolved"):
        parts.append("approach not resolved (bodies predicted into each other or past a wall)")
    if cost is not None:
        parts.append(str(cost))
    return "  ".join(parts)


class VerboseProgress:
    """A progress callback printing :func:`verbose_line` for every step (then calling ``inner``).

    Parameters
    ----------
    sim : fluidem.simulation.Simulation
        The simulation whose :meth:`~fluidem.simulation.Simulation.step_info` each line reports.
    stream : file-like
        Where the lines go (a text stream with a ``write`` method).
    inner : callable, optional
        A progress callback ``inner(step, n_steps, t, cost)`` called after each line.
    """

    def __init__(self, sim, stream, inner=None):
        self.sim, self.stream, self.inner = sim, stream, inner

    def __call__(self, k, n, t, cost):
        print(verbose_line(self.sim.step_info(), n, cost), file=self.stream, flush=True)
        if self.inner is not None:
            self.inner(k, n, t, cost)
