"""Edge structure from Triangle's neighbours equals the sorted construction, also after splits."""

import numpy as np
import triangle as tr

from fluidem.mesh.adjacency import edges_from_neighbors, split_with_neighbors
from fluidem.mesh.junctions import split_triangles
from fluidem.mesh.relax import mesh_topology


def _random_mesh(seed, n=400):
    rng = np.random.default_rng(seed)
    pts = rng.random((n, 2))
    out = tr.triangulate({"vertices": pts}, "Qn")
    return out["vertices"], out["triangles"].astype(np.int64), out["neighbors"].astype(np.int64)


def _edge_sets(edges, edge_tris):
    return {(int(a), int(b)): tuple(sorted((int(s), int(t)))) for (a, b), (s, t) in zip(edges, edge_tris)}


def test_edges_from_neighbors_match_sorted_topology():
    _, t, nb = _random_mesh(0)
    edges, edge_tris = edges_from_neighbors(t, nb)
    ref = mesh_topology(t)
    assert len(edges) == len(ref.edges)
    assert _edge_sets(edges, edge_tris) == _edge_sets(ref.edges, ref.edge_tris)


def test_split_keeps_neighbours_valid_including_adjacent_splits():
    pts, t, nb = _random_mesh(1)
    # split many triangles, among them pairs of neighbours and triangles on the boundary
    rng = np.random.default_rng(2)
    tri = np.unique(np.concatenate([rng.choice(len(t), 40, replace=False), nb[:20, 0][nb[:20, 0] >= 0], np.arange(20)]))
    new = len(pts) + np.arange(len(tri))
    t2, nb2 = split_with_neighbors(t, nb, tri, new)
    np.testing.assert_array_equal(t2, split_triangles(t, tri, new))
    edges, edge_tris = edges_from_neighbors(t2, nb2)
    ref = mesh_topology(t2)
    assert _edge_sets(edges, edge_tris) == _edge_sets(ref.edges, ref.edge_tris)
