r"""Fluid regions of one triangulation and the enclosed pockets among them: pressure references.

The pressure of incompressible flow with velocity conditions on the whole boundary of a fluid
region is fixed only up to a constant on that region.  A mesh can hold several regions that no
fluid connects: the fluid enclosed by a ring of touching bodies, or cut off from the rest of the
box by bodies in contact with a wall (:mod:`fluidem.mesh.contact_outline` meshes such *pores*
and reports their areas).  Each such *closed* region carries its own constant pressure mode

.. math::

    q_c = 1 \ \text{on region } c, \ 0 \ \text{elsewhere}: \qquad
    \int_\Omega q_c \, \nabla\!\cdot v \, dx = \oint_{\partial\Omega_c} v\cdot n \, ds = 0

for every velocity ``v`` that vanishes where conditions are set, so the saddle-point matrix is
singular once for every closed region; one pinned pressure DOF for the whole mesh regularises only
the region it lies in.  :func:`fluid_components` finds the regions once per triangulation, as the
connected components of the graph that joins every element to its free velocity DOFs and to its
pressure DOFs (elements that share a free velocity DOF or a pressure DOF exchange fluid or
pressure); a component is *open* when one of its free velocity DOFs lies on a boundary without a
condition (outflow, do-nothing), and *closed* otherwise.  :class:`fluidem.fluid.problem.FlowProblem`
pins one pressure DOF per closed component and shifts each closed component's pressure to zero mean
afterwards (Brezzi & Fortin 1991, Sec. VI.3: the pressure of a closed region is defined up to a
constant; fixing it by one value or by the mean gives the same velocity).

The same identity is a compatibility condition on the boundary data: with ``u_D`` the velocity
conditions lifted into the domain,

.. math::

    \frac{dA_c}{dt} = \oint_{\partial\Omega_c} u_D\cdot n \, ds = -\sum_{q \in c} (B u_D)_q ,

the rate at which the bodies bounding the region change its area (Reynolds' transport theorem;
``B`` assembles ``−q div u``, :mod:`fluidem.fluid.forms`; the sum runs over the pressure DOFs of
the region, whose nodal basis sums to one on it).  An incompressible fluid cannot follow a motion
with ``dA_c/dt ≠ 0``: with the pin the discrete divergence would be dropped in one DOF and the
solution would carry a point source there.
:func:`pocket_area_rates` evaluates it per step (one sparse product) and
:meth:`FlowProblem.check_pockets` stops with :class:`PocketError` instead.

Examples
--------
Two squares no fluid connects: the small left one walled all round (closed: a pocket), the right
one with a free side (open).

>>> import numpy as np
>>> from skfem import MeshTri
>>> from fluidem.fluid import FlowSpace, VelocityBC
>>> a = MeshTri.init_tensor(np.linspace(0, 1, 4), np.linspace(0, 1, 4))
>>> m = MeshTri(np.hstack([0.5 * a.p, a.p + [[2.0], [0.0]]]), np.hstack([a.t, a.t + a.p.shape[1]]))
>>> m = m.with_boundaries({"walls": lambda x: x[0] < 2.9, "free": lambda x: x[0] > 2.9})
>>> space = FlowSpace(m, "th")
>>> walls = np.concatenate([space.velocity_dofs("walls", c) for c in (0, 1)])
>>> fc = fluid_components(space, walls, ["free"])
>>> fc.n_components, fc.closed.tolist(), [round(float(v), 12) for v in fc.areas]
(2, [True, False], [0.25, 1.0])
>>> fc.pockets.tolist()
[0]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import SolverError

__all__ = ["FluidComponents", "PocketError", "fluid_components", "pocket_area_rates", "POCKET_RATE_TOL"]

#: A pocket's area rate ``|dA/dt|`` above this fraction of its boundary flux ``Σ_q |(B u_D)_q|`` stops the run
#: (:meth:`FlowProblem.check_pockets`).  Rigid motions are exact in every element pair, so a motion that keeps
#: the pocket's area gives round-off: measured 5e-17 for the translated frame of ``tests/test_stability_stress.py``;
#: its top bar pushed in gives 1, and the frame turned by a scene's constant body velocities (each bar on a
#: straight line, not on the circle: the area changes at second order) 3.1e-3 after one step.
POCKET_RATE_TOL = 1e-8


class PocketError(SolverError):
    """The prescribed motion of the bodies around an enclosed fluid pocket would change its area.

    Attributes
    ----------
    component : int
        The pocket (a component of :class:`FluidComponents`).
    area : float
        Its area, length².
    rate : float
        ``dA/dt`` the boundary data imposes, length²/time.
    boundaries : tuple of str
        Names of the boundaries around it.
    """

    def __init__(self, message: str, component: int, area: float, rate: float, boundaries=()):
        super().__init__(message)
        self.component, self.area, self.rate, self.boundaries = int(component), float(area), float(rate), \
            tuple(boundaries)


@dataclass(frozen=True)
class FluidComponents:
    """The fluid regions of one triangulation (:func:`fluid_components`).

    Attributes
    ----------
    element_label : (n_elements,) int
        Region of every element, ``0 .. n_components − 1``, numbered by their first element.
    pressure_label : (n_p,) int
        Region of every pressure DOF.
    closed : (n_components,) bool
        No free velocity DOF of the region lies on a boundary without a condition: its pressure has
        no reference.
    areas : (n_components,) float
        Area of every region, length².
    boundaries : tuple of tuple of str
        Names of the mesh boundaries each region touches.
    """

    element_label: np.ndarray
    pressure_label: np.ndarray
    closed: np.ndarray
    areas: np.ndarray
    boundaries: tuple

    @property
    def n_components(self) -> int:
        return len(self.closed)

    @property
    def pockets(self) -> np.ndarray:
        """The enclosed pockets: closed regions other than the largest region of the mesh, (k,) int."""
        if self.n_components < 2:
            return np.zeros(0, np.int64)
        big = int(np.argmax(self.areas))
        c = np.flatnonzero(self.closed)
        return c[c != big]

    def pins(self, preferred: int, eligible: np.ndarray | None = None) -> np.ndarray:
        """One pressure DOF (index among the pressure DOFs) per closed region: ``preferred`` in its own
        region, else the region's lowest ``eligible`` DOF (all by default); (n_closed,) int, in the
        order of the closed regions."""
        lab = self.pressure_label
        q = np.arange(len(lab)) if eligible is None else np.flatnonzero(eligible)
        first = np.full(self.n_components, len(lab), np.int64)
        np.minimum.at(first, lab[q], q)
        first[lab[preferred]] = preferred
        out = first[self.closed]
        if (out >= len(lab)).any():  # a closed region without an eligible DOF: any of its DOFs
            any_q = np.full(self.n_components, len(lab), np.int64)
            np.minimum.at(any_q, lab, np.arange(len(lab)))
            out = np.where(out >= len(lab), any_q[self.closed], out)
        return out

    def text(self) -> str:
        """One line for a log: the regions, the closed ones and the pockets with their areas.

        >>> fc = FluidComponents(np.zeros(2, int), np.zeros(6, int), np.array([False]), np.array([2.0]), ((),))
        >>> fc.text()
        '1 fluid region (open)'
        """
        n, k = self.n_components, len(self.pockets)
        s = f"{n} fluid region{'s' * (n != 1)} ({int(self.closed.sum())} closed)" if n > 1 else \
            "1 fluid region (" + ("closed" if self.closed[0] else "open") + ")"
        if k:
            s += f"; {k} enclosed pocket{'s' * (k != 1)} of area " + \
                 ", ".join(f"{a:.3g}" for a in self.areas[self.pockets]) + ", each with its own pressure reference"
        return s


def fluid_components(space, dirichlet_dofs, natural_boundaries, rep=None) -> FluidComponents:
    """The fluid regions of ``space``'s mesh and which of them are closed (module docstring).

    Built once per triangulation: one sparse graph of elements, velocity DOFs, pressure DOFs and an
    "outside" node (joined to the free velocity DOFs on ``natural_boundaries``), and one call of
    :func:`scipy.sparse.csgraph.connected_components`.

    Parameters
    ----------
    space : FlowSpace
    dirichlet_dofs : (k,) int
        Velocity DOFs with a condition (indices into the velocity DOFs, ``< n_u``).
    natural_boundaries : sequence of str
        Boundaries with no velocity condition (outflow).
    rep : (n_u + n_p,) int, optional
        Representative of every DOF (periodic sides, :mod:`fluidem.fluid.periodic`): identified
        DOFs join their regions.

    Returns
    -------
    FluidComponents
    """
    n_u, n_p = space.n_u, space.n_p
    mesh = space.mesh
    ne = mesh.t.shape[1]
    rep = np.arange(n_u + n_p) if rep is None else np.asarray(rep)
    free_u = np.ones(n_u, bool)
    free_u[np.asarray(dirichlet_dofs, np.int64)] = False
    ed_u = np.asarray(space.ub.element_dofs)  # (nb_u, ne)
    ed_p = np.asarray(space.pb.element_dofs)  # (nb_p, ne)
    el_u = np.broadcast_to(np.arange(ne), ed_u.shape)
    keep = free_u[ed_u]
    el_p = np.broadcast_to(np.arange(ne), ed_p.shape)
    out = ne + n_u + n_p
    nat = [space.velocity_dofs(b, c) for b in natural_boundaries for c in (0, 1)]
    nat = np.concatenate(nat).astype(np.int64) if nat else np.zeros(0, np.int64)
    nat = nat[free_u[nat]]
    rows = np.concatenate([el_u[keep], el_p.ravel(), ne + rep[nat]])
    cols = np.concatenate([ne + rep[ed_u[keep]], ne + rep[n_u + ed_p.ravel()], np.full(len(nat), out)])
    G = sp.coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(out + 1, out + 1)).tocsr()
    _, lab = connected_components(G, directed=False)
    # number the regions by their first element
    el_lab = lab[:ne]
    uniq, first, el_label = np.unique(el_lab, return_index=True, return_inverse=True)
    order = np.argsort(first)
    renum = np.empty_like(order)
    renum[order] = np.arange(len(order))
    el_label = renum[el_label]
    to_region = np.full(lab.max() + 1, -1, np.int64)
    to_region[uniq] = renum
    p_label = to_region[lab[ne + rep[n_u + np.arange(n_p)]]]
    closed = np.ones(len(uniq), bool)
    if lab[out] in set(uniq.tolist()):
        closed[to_region[lab[out]]] = False
    p, t = mesh.p, mesh.t
    e1, e2 = p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]
    areas = np.bincount(el_label, weights=0.5 * np.abs(e1[0] * e2[1] - e1[1] * e2[0]), minlength=len(uniq))
    bnd = mesh.boundaries or {}
    names = sorted(bnd)
    if names:
        fac = np.concatenate([np.asarray(bnd[b]) for b in names])
        who = np.repeat(np.arange(len(names)), [len(bnd[b]) for b in names])
        pairs = np.unique(np.column_stack([el_label[mesh.f2t[0, fac]], who]), axis=0)
        boundaries = tuple(tuple(names[j] for j in pairs[pairs[:, 0] == c, 1]) for c in range(len(uniq)))
    else:
        boundaries = tuple(() for _ in range(len(uniq)))
    return FluidComponents(el_label, p_label, closed, areas, boundaries)


def pocket_area_rates(problem, t: float, components=None) -> tuple[np.ndarray, np.ndarray]:
    """``dA/dt`` the velocity conditions at ``t`` impose on every region, and its boundary flux scale.

    Parameters
    ----------
    problem : FlowProblem
    t : float
        Time of the conditions.
    components : array_like of int, optional
        Regions to return (all by default).

    Returns
    -------
    rate : (k,) float
        ``−Σ_{q ∈ c} (B u_D)_q = ∮ u_D · n``, length²/time (module docstring; B assembles −q div u).
    scale : (k,) float
        ``Σ_{q ∈ c} |(B u_D)_q|``, length²/time: the flux through the region's boundary layer of
        elements without cancellation, the yardstick of :data:`POCKET_RATE_TOL`.
    """
    fc = problem.components
    d, v = problem.dirichlet_values(t)
    u = np.zeros(problem.space.n_u)
    u[d] = v
    div = problem.B @ u
    n = fc.n_components
    rate = -np.bincount(fc.pressure_label, weights=div, minlength=n)  # B: −q div u (fluidem.fluid.forms)
    scale = np.bincount(fc.pressure_label, weights=np.abs(div), minlength=n)
    if components is not None:
        c = np.asarray(components, np.int64)
        return rate[c], scale[c]
    return rate, scale
