"""Gear predictor–corrector for second-order equations of motion (Gear 1971).

The state of each coordinate (x, y and the angle of every body) is the vector of its
time derivatives ``X_k = d^k x / dt^k``, k = 0 … q−1.  One step:

* predict with the Taylor (Pascal-triangle) matrix,
  ``X_k^p = Σ_{m ≥ k} X_m dt^(m−k) / (m−k)!``;
* evaluate the acceleration ``a`` at the predicted positions and velocities (for q = 3 the
  DEM hands the forces the mid-step velocity instead, :mod:`fluidem.dem.system`, "Velocity");
* correct with ``Δ = (a − X_2^p) dt² / 2``, ``X_k ← X_k^p + c_k Δ k! / dt^k``.

Corrector coefficients ``c_k`` for second-order equations (Gear 1971; Allen &
Tildesley 1987, table E.2; Matuttis & Chen 2014, ch. 2):

=========  ==========================================
q values   c_0 … c_{q−1}
=========  ==========================================
3          0, 1, 1                (2nd order; identical to velocity Verlet)
4          1/6, 5/6, 1, 1/3
5          19/120, 3/4, 1, 1/2, 1/12
6          3/16, 251/360, 1, 11/18, 1/6, 1/60   (5th order)
=========  ==========================================

The 2nd-order (3-value) scheme is the default: it is symplectic for velocity-independent
forces, so an undamped collision conserves energy and a static packing does not drift.
Storing unscaled derivatives lets the step size change between steps.
"""

from __future__ import annotations

from math import factorial

import numpy as np

from fluidem import validate

__all__ = ["GEAR_COEFFICIENTS", "GEAR_ORDERS", "Gear"]

GEAR_COEFFICIENTS = {
    3: (0.0, 1.0, 1.0),
    4: (1.0 / 6.0, 5.0 / 6.0, 1.0, 1.0 / 3.0),
    5: (19.0 / 120.0, 3.0 / 4.0, 1.0, 1.0 / 2.0, 1.0 / 12.0),
    6: (3.0 / 16.0, 251.0 / 360.0, 1.0, 11.0 / 18.0, 1.0 / 6.0, 1.0 / 60.0),
}


#: The predictor orders :class:`Gear` offers (q = order + 1 values per coordinate).
GEAR_ORDERS = tuple(q - 1 for q in GEAR_COEFFICIENTS)


class Gear:
    """Gear predictor–corrector state for ``n`` coordinates.

    Parameters
    ----------
    x : (n,) float
        Positions.
    v : (n,) float
        Velocities.
    a : (n,) float
        Accelerations at the initial state.
    order : int
        Order of the predictor polynomial, 2 (default, 3 values) to 5 (6 values).
    """

    def __init__(self, x, v, a, order: int = 2):
        q = int(validate.choice("Gear(order=...)", order, GEAR_ORDERS)) + 1
        self.q = q
        self.c = np.array(GEAR_COEFFICIENTS[q])
        x = np.asarray(x, float)
        self.X = np.zeros((q,) + x.shape)
        self.X[0], self.X[1], self.X[2] = x, v, a
        self._pred = None

    def predict(self, dt: float, mask=None) -> tuple[np.ndarray, np.ndarray]:
        """Predicted positions and velocities at ``t + dt`` (the state is kept until :meth:`correct`).

        ``mask`` (bool, shape of ``x``) selects the coordinates that move; the others
        keep their current values.
        """
        q = self.q
        P = self.X.copy()
        for k in range(q - 1):
            for m in range(k + 1, q):
                P[k] += self.X[m] * (dt ** (m - k) / factorial(m - k))
        if mask is not None:
            P = np.where(mask, P, self.X)
        self._pred = (P, dt, mask)
        return P[0], P[1]

    def correct(self, a) -> None:
        """Correct the predicted state with the accelerations ``a`` evaluated at it."""
        P, dt, mask = self._pred
        delta = (np.asarray(a, float) - P[2]) * (0.5 * dt * dt)
        for k in range(self.q):
            if self.c[k] != 0.0:
                P[k] += self.c[k] * delta * (factorial(k) / dt**k)
        self.X = P if mask is None else np.where(mask, P, self.X)
        self._pred = None

    def set(self, x=None, v=None, a=None, mask=None) -> None:
        """Overwrite positions, velocities or accelerations (where ``mask``); higher derivatives are zeroed there."""
        m = np.ones(self.X.shape[1:], bool) if mask is None else mask
        for k, val in ((0, x), (1, v), (2, a)):
            if val is not None:
                self.X[k] = np.where(m, val, self.X[k])
        if x is not None or v is not None:
            for k in range(3, self.q):
                self.X[k] = np.where(m, 0.0, self.X[k])

    @property
    def x(self):
        return self.X[0]

    @property
    def v(self):
        return self.X[1]

    @property
    def a(self):
        return self.X[2]
