"""The built-in granular step collapsing in a viscous liquid (``column-collapse-fluid``) and its dry twin
(``column-collapse-fluid-dry``): the twins share grains, box and contact law (its body table is the
documented ``fluidem fill`` command: ``tests/test_fill.py``), and the first steps of the coupled run
keep the fluid domain the box less the grains, the grains in the box and apart, while the front of the
step moves out."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from fluidem.cases.scenes import example_scene


def test_dry_twin_has_the_same_grains_box_and_contacts():
    wet, dry = example_scene("column-collapse-fluid"), example_scene("column-collapse-fluid-dry")
    assert wet.fluid is not None and dry.fluid is None
    assert len(wet.bodies) == len(dry.bodies) >= 200
    for a, b in zip(wet.world_outlines(), dry.world_outlines()):
        assert np.array_equal(a, b)
    assert [b.density for b in wet.bodies] == [b.density for b in dry.bodies]
    assert wet.domain.box == dry.domain.box and wet.gravity == dry.gravity
    assert (wet.contact.E, wet.contact.mu, wet.contact.gamma) == (dry.contact.E, dry.contact.mu, dry.contact.gamma)
    # a step L0 = H0 = 0.19 m of polygons only, at the area fraction fluidem fill reports (0.3551)
    outlines = wet.world_outlines()
    assert {b.shape for b in wet.bodies} == {"polygon", "rectangle"}
    phi = sum(shapely.area(shapely.Polygon(v)) for v in outlines) / 0.19**2
    assert phi == pytest.approx(0.3551, abs=5e-5)
    assert max(v[:, 0].max() for v in outlines) < 0.19 and max(v[:, 1].max() for v in outlines) < 0.19


@pytest.mark.slow(seconds=30)  # 10 steps: 8 s of stepping at load 3 (5 steps of 0.01 s: 27 s at load 3.5)
def test_first_steps_keep_the_fluid_domain_and_move_the_front():
    """Ten coupled steps (dt = 0.005 s, t = 0.05 s): the triangulated fluid area is the box less the grains to
    round-off (the mesh fits every outline), every grain stays in the box, no two grains overlap by more
    than the contact law's scale, and the front of the step (the rightmost grain vertex) has moved out."""
    from fluidem.simulation import Simulation

    scene = example_scene("column-collapse-fluid")
    sim = Simulation(scene)
    front0 = max(v[:, 0].max() for v in scene.world_outlines())
    sim.run(out_dir=None, n_steps=10)
    assert sim.step_index == 10
    outlines = [b.world_vertices(position=x, angle=a)
                for b, x, a in zip(scene.bodies, sim.bodies.positions, sim.bodies.angles)]
    polys = [shapely.Polygon(v) for v in outlines]
    grains = sum(p.area for p in polys)
    p, t = sim.flow.mesh.p, sim.flow.mesh.t
    e1, e2 = p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]
    fluid = 0.5 * np.abs(e1[0] * e2[1] - e1[1] * e2[0]).sum()
    assert abs(fluid + grains - 1.0 * 0.3) < 1e-12  # measured 5.6e-17 (6000 triangles, 200 polygons)
    W = np.vstack(outlines)
    assert W[:, 0].min() > 0 and W[:, 0].max() < 1.0 and W[:, 1].min() > 0 and W[:, 1].max() < 0.3
    tree = shapely.STRtree(polys)
    i, j = tree.query(polys, predicate="intersects")
    pair = i < j
    overlap = max([polys[a].intersection(polys[b]).area / min(polys[a].area, polys[b].area)
                   for a, b in zip(i[pair], j[pair])], default=0.0)
    assert overlap < 0.01  # measured 0: no overlap yet, the repulsion keeps the gaps
    front = W[:, 0].max()
    assert front - front0 > 1e-3  # measured 2.9e-3 m in 0.05 s (3.0e-3 at dt = 0.01)
    assert math.isfinite(float(np.abs(sim.bodies.velocities).max()))
