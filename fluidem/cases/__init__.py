"""Built-in cases: DFG 2D-1/2D-2/2D-3, the square cylinder at Re = 100, a settling disk and
drafting–kissing–tumbling."""

from .base import CASES, CaseResult, get_case  # noqa: F401
from . import dfg, square_cylinder, settling, dkt  # noqa: F401  (register the cases, in the registry's order)
