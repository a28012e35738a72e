"""Element pairs for velocity and pressure, registered by the names users type.

======  ==========================================  =============================================
name    velocity / pressure                         notes
======  ==========================================  =============================================
p2b     P2 + cubic bubble / discontinuous P1        Crouzeix–Raviart; "quasi-third order" of the
                                                    paper (Sec. 3.1), locally mass conserving;
                                                    the default for particle flows
th      P2 / P1                                     Taylor–Hood
p3      P3 / P2                                     Taylor–Hood of one order higher: most digits
                                                    per second on the steady cylinder benchmark
mini    P1 + cubic bubble / P1                      MINI; cheapest, first order
======  ==========================================  =============================================

All pairs are inf-sup stable (Boffi, Brezzi & Fortin, *Mixed Finite Element Methods*, 2013,
Ch. 8).  ``quadrature_order`` integrates the convection trilinear form exactly on straight
elements (degree of u + degree of ∇u + degree of v).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from skfem import (
    ElementTriMini,
    ElementTriP1,
    ElementTriP1DG,
    ElementTriP2,
    ElementTriP2B,
    ElementTriP3,
)

__all__ = ["ElementPair", "ELEMENT_PAIRS", "element_pair"]


@dataclass(frozen=True)
class ElementPair:
    """A velocity/pressure element pair."""

    name: str
    velocity: Callable  # scalar velocity element class (wrapped in ElementVector by the space)
    pressure: Callable
    velocity_degree: int
    pressure_discontinuous: bool
    description: str

    @property
    def quadrature_order(self) -> int:
        k = self.velocity_degree
        return k + (k - 1) + k


ELEMENT_PAIRS: dict[str, ElementPair] = {
    "p2b": ElementPair("p2b", ElementTriP2B, ElementTriP1DG, 3, True,
                       "P2+bubble velocity / discontinuous P1 pressure (Crouzeix-Raviart)"),
    "th": ElementPair("th", ElementTriP2, ElementTriP1, 2, False, "P2/P1 Taylor-Hood"),
    "p3": ElementPair("p3", ElementTriP3, ElementTriP2, 3, False, "P3/P2 Taylor-Hood"),
    "mini": ElementPair("mini", ElementTriMini, ElementTriP1, 3, False, "P1+bubble/P1 MINI"),
}


def element_pair(name: str) -> ElementPair:
    """Look up an element pair by name; ``ValueError`` lists the allowed names."""
    try:
        return ELEMENT_PAIRS[name]
    except (KeyError, TypeError):
        allowed = ", ".join(repr(k) for k in ELEMENT_PAIRS)
        raise ValueError(f"unknown element pair {name!r}; allowed: {allowed}") from None
