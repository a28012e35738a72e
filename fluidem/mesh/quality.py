"""Mesh quality: angles, inverted elements, narrow gaps, and oscillating nodes (paper Sec. 2.2, 3.3).

Rule of thumb (van Kan et al., REFERENCES.md "Meshes"): no triangle angle above 135°;
equilateral triangles give the best-conditioned FEM systems.

*Narrow-gap triangles* are those that lie in a gap between two different boundaries
(two bodies, or a body and the box) narrower than half the local target size: there a
triangle cannot be well shaped without nodes the gap has no room for, so these triangles
are counted on their own and left out of the angle statistics.  A triangle counts as
narrow-gap when its centroid ``c`` has ``d1 + d2 < h/2``, with ``d1``, ``d2`` the distances
from ``c`` to the nearest and second-nearest distinct boundary and ``h`` the mean target
size of its vertices, or when it is anchored across such a gap: one of its edges joins two
different boundaries and one end of that edge is closer than ``h/2`` to the other end's
boundary (the elements at the mouth of a narrow gap).  The classification itself lives in
:class:`fluidem.mesh.MovingMesh`, which knows the bodies.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .relax import signed_areas

__all__ = ["MeshQuality", "triangle_angles", "mesh_quality", "OscillationDetector"]


@dataclass(frozen=True)
class MeshQuality:
    """Quality statistics of a triangle mesh.

    Angles in degrees.  ``min_angle``, ``max_angle`` and ``frac_above_135`` exclude the
    ``n_narrow_gap_triangles`` narrow-gap triangles (see module docstring); the ``*_all``
    fields include them.
    """

    min_angle: float
    max_angle: float
    frac_above_135: float
    n_inverted: int
    n_nodes_inside_bodies: int
    n_nodes: int
    n_triangles: int
    n_narrow_gap_triangles: int
    min_angle_all: float = float("nan")
    max_angle_all: float = float("nan")
    min_area: float = float("nan")

    def __str__(self) -> str:
        return (
            f"MeshQuality(nodes={self.n_nodes}, triangles={self.n_triangles}, "
            f"angles [{self.min_angle:.1f}°, {self.max_angle:.1f}°], "
            f">135°: {100 * self.frac_above_135:.3f} %, inverted={self.n_inverted}, "
            f"inside bodies={self.n_nodes_inside_bodies}, narrow-gap={self.n_narrow_gap_triangles} "
            f"(all: [{self.min_angle_all:.1f}°, {self.max_angle_all:.1f}°]))"
        )


def triangle_angles(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Interior angles ``(n_triangles, 3)`` in degrees (angle at vertex k in column k)."""
    p = points[triangles]  # (m, 3, 2)
    e0 = p[:, 2] - p[:, 1]  # opposite vertex 0
    e1 = p[:, 0] - p[:, 2]
    e2 = p[:, 1] - p[:, 0]
    l0 = np.einsum("ij,ij->i", e0, e0)
    l1 = np.einsum("ij,ij->i", e1, e1)
    l2 = np.einsum("ij,ij->i", e2, e2)
    # law of cosines, clipped for round-off
    with np.errstate(invalid="ignore", divide="ignore"):
        c0 = (l1 + l2 - l0) / (2 * np.sqrt(l1 * l2))
        c1 = (l0 + l2 - l1) / (2 * np.sqrt(l0 * l2))
    a0 = np.degrees(np.arccos(np.clip(c0, -1, 1)))
    a1 = np.degrees(np.arccos(np.clip(c1, -1, 1)))
    return np.column_stack([a0, a1, 180.0 - a0 - a1])


def mesh_quality(points, triangles, narrow=None, n_inside: int = 0) -> MeshQuality:
    """Quality statistics of ``triangles`` ``(m, 3)`` on ``points`` ``(n, 2)``.

    Parameters
    ----------
    narrow : (m,) bool or None
        Narrow-gap triangles, left out of the angle statistics.
    n_inside : int
        Number of nodes inside bodies (computed by the caller, who knows the bodies).
    """
    p = np.asarray(points, dtype=float)
    t = np.asarray(triangles)
    area = signed_areas(p, t)
    ang = triangle_angles(p, t)
    narrow = np.zeros(len(t), dtype=bool) if narrow is None else np.asarray(narrow, dtype=bool)
    good = ~narrow
    a = ang[good]
    return MeshQuality(
        min_angle=float(a.min()) if a.size else float("nan"),
        max_angle=float(a.max()) if a.size else float("nan"),
        frac_above_135=float((a > 135.0).mean()) if a.size else 0.0,
        n_inverted=int((area <= 0).sum()),
        n_nodes_inside_bodies=int(n_inside),
        n_nodes=int(len(np.unique(t))) if len(t) else 0,
        n_triangles=int(len(t)),
        n_narrow_gap_triangles=int(narrow.sum()),
        min_angle_all=float(ang.min()) if ang.size else float("nan"),
        max_angle_all=float(ang.max()) if ang.size else float("nan"),
        min_area=float(area.min()) if area.size else float("nan"),
    )


@dataclass
class OscillationDetector:
    """Detect nodes that flip between two positions step after step (paper Sec. 3.3).

    A node *flips* in a physical step when its relaxation displacement ``d_n`` reverses the
    previous one (``d_n · d_{n−1} < −0.5 |d_n| |d_{n−1}|``), returns close to where it was
    two steps before (``|d_n + d_{n−1}| < 0.5 |d_n|``) and moves more than ``tol`` times its
    target size.  It is reported as *oscillating* after ``min_flips`` flips in a row.

    Parameters
    ----------
    tol : float
        Displacement threshold relative to the node's target size.
    min_flips : int
        Consecutive flips before a node is reported.
    """

    tol: float = 1e-3
    min_flips: int = 3
    _prev: np.ndarray | None = field(default=None, repr=False)
    _count: np.ndarray | None = field(default=None, repr=False)

    def reset(self) -> None:
        """Forget the history (after a re-triangulation, node numbers change)."""
        self._prev = None
        self._count = None

    def update(self, displacement: np.ndarray, h_node: np.ndarray) -> np.ndarray:
        """Feed the relaxation displacement ``(n, 2)`` of one step; return oscillating node indices."""
        d = np.asarray(displacement, dtype=float)
        if self._prev is None or len(self._prev) != len(d):
            self._prev = d.copy()
            self._count = np.zeros(len(d), dtype=np.int64)
            return np.zeros(0, dtype=np.int64)
        # by columns (the same sums of two terms as along axis 1, without (n, 2) temporaries)
        dx, dy = d[:, 0], d[:, 1]
        px, py = self._prev[:, 0], self._prev[:, 1]
        dn = np.sqrt(dx * dx + dy * dy)
        dp = np.sqrt(px * px + py * py)
        dot = dx * px + dy * py
        bx, by = dx + px, dy + py
        back = np.sqrt(bx * bx + by * by)
        flip = (dot < -0.5 * dn * dp) & (back < 0.5 * dn) & (dn > self.tol * h_node)
        self._count = np.where(flip, self._count + 1, 0)
        self._prev = d.copy()
        return np.flatnonzero(self._count >= self.min_flips)
