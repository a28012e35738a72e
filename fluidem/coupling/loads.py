"""Hydrodynamic loads on the bodies from the residual of the last solve.

The loads of all bodies are one mat-vec with the rigid-mode operator
(:class:`fluidem.fluid.forces.RigidModes`, built with the space; on a moved mesh its torque
rows are refilled), F · e = −ρ R(u, p; v_e) (John 2004, Sec. 3).
"""

from __future__ import annotations

import numpy as np

__all__ = ["FlowLoads"]


class FlowLoads:
    """Mix-in of both flows: ``loads()`` -> forces (n_bodies, 2), torques (n_bodies,).

    Needs ``self.stokes``, ``self.problem``, ``self.x`` (Stokes), ``self.stepper``
    (Navier–Stokes), ``self.rigid`` (a RigidModes) and ``self.rho``.
    """

    def residual(self) -> np.ndarray:
        """Residual (n_dofs,) of the last solve's equations, no conditions applied (kinematic units)."""
        if self.stokes:
            return self.problem.steady_residual(self.x, convection=False)
        return self.stepper.last_residual()

    def loads(self):
        """Forces (n_bodies, 2) and torques (n_bodies,) of the fluid on the bodies."""
        return self.rigid.loads(self.residual(), rho=self.rho)
