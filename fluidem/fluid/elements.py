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

from .. import names

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


#: Element pairs by the names of kind ``"element"`` in :mod:`fluidem.names` (same keys, same order).
ELEMENT_PAIRS: dict[str, ElementPair] = {
    "p2b": ElementPair("p2b", ElementTriP2B, ElementTriP1DG, 3, True,
                       "P2+bubble velocity / discontinuous P1 pressure (Crouzeix-Raviart)"),
    "th": ElementPair("th", ElementTriP2, ElementTriP1, 2, False, "P2/P1 Taylor-Hood"),
    "p3": ElementPair("p3", ElementTriP3, ElementTriP2, 3, False, "P3/P2 Taylor-Hood"),
    "mini": ElementPair("mini", ElementTriMini, ElementTriP1, 3, False, "P1+bubble/P1 MINI"),
}


def element_pair(name: str, where: str = "element") -> ElementPair:
    """The element pair called ``name`` (a name or alias of kind ``"element"``).

    Parameters
    ----------
    name : str
        ``"p2b"``, ``"th"``, ``"p3"`` or ``"mini"``.
    where : str
        Where the name was typed, for the error message (a scene key, an option).

    Returns
    -------
    ElementPair

    Raises
    ------
    fluidem.errors.InputError
        For an unknown name (a ``ValueError``), in the one format of :mod:`fluidem.names`.

    Examples
    --------
    >>> element_pair("th").pressure.__name__, element_pair("p2b").quadrature_order
    ('ElementTriP1', 8)
    >>> element_pair("p1")
    Traceback (most recent call last):
    ...
    fluidem.errors.InputError: element = 'p1': expected one of 'p2b', 'th', 'p3', 'mini' (element pair)
    """
    return ELEMENT_PAIRS[names.lookup("element", name, where=where)]
