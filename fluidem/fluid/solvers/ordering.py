"""Which SuperLU ordering to factorise a run's continuous-pressure systems with: :class:`OrderingChoice`.

SuperLU offers two good orderings for a saddle-point matrix with a continuous pressure
(Taylor–Hood, P3/P2, MINI): the symmetric minimum-degree ordering of Kᵀ + K in symmetric mode
(``"mmd"``, diagonal pivot threshold 1e-3) and the column approximate minimum-degree ordering
COLAMD with threshold partial pivoting (``"colamd"``, threshold 0.01).  Neither wins
everywhere.  Measured on the second step of built-in examples (Taylor–Hood, one thread; entries
of L + U and factorisation seconds, mmd / colamd):

==========================================  ======  ==============  ==============
system                                      DOFs    mmd             colamd
==========================================  ======  ==============  ==============
``dfg-cylinder`` (Navier–Stokes, fixed)     11 610  1.22M, 0.13 s   2.01M, 0.18 s
``jeffery-orbit`` (Stokes, one free body)   11 480  4.51M, 0.52 s   6.27M, 0.86 s
``wall-correction`` (Stokes, driven body)   12 842  3.08M, 0.49 s   1.72M, 0.17 s
``sheared-suspension`` (Stokes, 20 bodies)  10 307  9.15M, 1.68 s   4.65M, 0.36 s
==========================================  ======  ==============  ==============

The symmetric mode keeps the ordering only while it can pivot on the diagonal; the zero
pressure diagonal of the saddle point makes it pivot off the diagonal, and how much fill that
costs depends on the mesh and the bodies.  So a run measures: the first factorisation with each
ordering, then the one with less fill per matrix entry, the other tried again every
:data:`REMEASURE_EVERY` factorisations (the geometry of a moving-mesh run changes).  The fill
(entries of L + U) decides, not the clock: it follows the time in every case above and is
the same on every run of the same scene, so the choice (and the round-off of the solution)
does not depend on the machine's load.

Examples
--------
>>> choice = OrderingChoice()
>>> choice.next()                       # each ordering is measured once first
'mmd'
>>> choice.record("mmd", fill=9.0e6, entries=2.8e5)
>>> choice.next()
'colamd'
>>> choice.record("colamd", fill=4.6e6, entries=2.8e5)
>>> choice.next(), choice.counts
('colamd', {'mmd': 1, 'colamd': 1})
"""

from __future__ import annotations

__all__ = ["OrderingChoice", "ORDERINGS", "REMEASURE_EVERY"]

#: the orderings compared, in the order they are first tried (the first is the former default)
ORDERINGS = ("mmd", "colamd")
#: factorisations between two measurements of the ordering not in use
REMEASURE_EVERY = 16


class OrderingChoice:
    """The SuperLU ordering for the next factorisation of a run, chosen by measured fill.

    Attributes
    ----------
    fill_ratio : dict
        Ordering -> entries of L + U over entries of K at its last measurement (absent until
        measured).
    counts : dict
        Ordering -> factorisations done with it.
    since_measured : int
        Factorisations since the ordering not in use was last measured.
    """

    def __init__(self):
        self.fill_ratio: dict = {}
        self.counts: dict = dict.fromkeys(ORDERINGS, 0)
        self.since_measured = 0

    def best(self) -> str:
        """The measured ordering with the least fill per entry (the first one before any is measured)."""
        measured = [o for o in ORDERINGS if o in self.fill_ratio]
        return min(measured, key=lambda o: self.fill_ratio[o]) if measured else ORDERINGS[0]

    def next(self) -> str:
        """The ordering to factorise with next: an unmeasured one first, then the best, and the
        other one again once every :data:`REMEASURE_EVERY` factorisations."""
        for o in ORDERINGS:
            if o not in self.fill_ratio:
                return o
        best = self.best()
        if self.since_measured >= REMEASURE_EVERY:
            return next(o for o in ORDERINGS if o != best)
        return best

    def record(self, ordering: str, fill: float, entries: float) -> None:
        """A factorisation with ``ordering`` had ``fill`` entries in L + U for a matrix of ``entries``."""
        was_best = ordering == self.best() and ordering in self.fill_ratio
        self.fill_ratio[ordering] = float(fill) / max(float(entries), 1.0)
        self.counts[ordering] = self.counts.get(ordering, 0) + 1
        self.since_measured = self.since_measured + 1 if was_best else 0

    def state(self) -> dict:
        """The choice as plain values (a checkpoint keeps it, so a restart factorises as the run did)."""
        return {"fill_ratio": dict(self.fill_ratio), "counts": dict(self.counts),
                "since_measured": int(self.since_measured)}

    def restore(self, state: dict | None) -> None:
        """Take the choice of :meth:`state` in place (the solvers built so far share this object);
        ``None`` (a checkpoint written before the choice existed) starts afresh."""
        self.__init__()
        if state:
            self.fill_ratio = {str(k): float(v) for k, v in state["fill_ratio"].items()}
            self.counts.update({str(k): int(v) for k, v in state["counts"].items()})
            self.since_measured = int(state["since_measured"])

    def summary(self) -> str:
        """One line: factorisations per ordering and the last fill per entry of each."""
        parts = [f"{o} {self.counts.get(o, 0)}" + (f" (fill {self.fill_ratio[o]:.1f}x)" if o in self.fill_ratio
                                                    else "") for o in ORDERINGS]
        return "SuperLU orderings: " + ", ".join(parts)
