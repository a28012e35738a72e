"""Hydrodynamic loads on the bodies from the residual of the last solve.

The loads of all bodies are one mat-vec with the rigid-mode operator
(:class:`fluidem.fluid.forces.RigidModes`, built with the space; on a moved mesh its torque
rows are refilled), F · e = −ρ R(u, p; v_e) (John 2004, Sec. 3).
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

__all__ = ["FlowLoads"]


class FlowLoads:
    """Mix-in of both flows: ``loads()`` -> forces (n_bodies, 2), torques (n_bodies,).

    Needs ``self.stokes``, ``self.problem``, ``self.x`` (Stokes), ``self.stepper``
    (Navier–Stokes), ``self.rigid`` (a RigidModes) and ``self.rho``.
    """

    def residual(self) -> np.ndarray:
        """Residual (n_dofs,) of the last solve's equations, no conditions applied (kinematic units).
        Inside :meth:`residual_held` computed once and then returned again."""
        held = self.__dict__.get("_held_residual")
        if held:
            return held[0]
        r = (self.problem.steady_residual(self.x, convection=False) if self.stokes
             else self.stepper.last_residual())
        if held is not None:
            held.append(r)
        return r

    @contextmanager
    def residual_held(self):
        """Inside, :meth:`residual` is evaluated once: for the bodies' loads and the sides' forces of one
        recorded step (a residual is a pass over all elements: 0.4–0.5 s at 1.57M DOFs).  The state must not
        change inside."""
        self._held_residual = []
        try:
            yield self
        finally:
            self._held_residual = None

    def loads(self):
        """Forces (n_bodies, 2) and torques (n_bodies,) of the fluid on the bodies."""
        return self.rigid.loads(self.residual(), rho=self.rho)
