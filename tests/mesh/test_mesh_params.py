"""MeshParams: the moving mesh's parameters, validated once; keywords and ``params=`` agree."""

import numpy as np
import pytest

from fluidem.errors import InputError, MeshError
from fluidem.geometry import rectangle, regular_polygon
from fluidem.mesh import STRATEGIES, MeshParams, MovingMesh


def _scene():
    bodies = [regular_polygon(0.3, 6), rectangle(0.5, 0.3), regular_polygon(0.25, 3)]
    poses = np.array([[1.0, 1.0, 0.0], [2.0, 1.2, 0.3], [1.5, 2.0, 0.1]])
    return (0, 3, 0, 3), bodies, poses


def test_defaults_are_the_former_keyword_defaults():
    p = MeshParams()
    assert (p.strategy, p.retriangulate_every, p.relax_iterations, p.min_angle_trigger, p.clearance,
            p.purge_clearance, p.min_gap, p.junctions, p.background, p.initial_iterations, p.drag_reach,
            p.drag_full, p.drag_stiffness, p.gap_purge, p.cleanup_passes, p.retriangulate_iterations,
            p.tow_width, p.refine_area, p.coarsen_ratio) == (
        "drag", 30, None, 15.0, 0.5, 0.3, None, True, None, 60, 3.0, 1.0, 0.8, 1.1, 2, 20, 2.0, 1.6, 0.7)
    assert p.drag_field == "harmonic"  # two clean-up passes and the harmonic drag: the re-triangulation cadence
    assert p.step_iterations == 3 and MeshParams(strategy="regenerate").step_iterations == 20
    assert p.min_gap_for(0.1) == 1e-3 * 0.1 and MeshParams(min_gap=0.01).min_gap_for(0.1) == 0.01
    assert STRATEGIES == ("drag", "regenerate", "fixed")


def test_keywords_and_params_build_the_same_mesh():
    dom, bodies, poses = _scene()
    a = MovingMesh(dom, bodies, poses, h=0.1, retriangulate_every=5, drag_reach=2.0)
    b = MovingMesh(dom, bodies, poses, h=0.1, params=MeshParams(retriangulate_every=5, drag_reach=2.0))
    # keywords override params
    c = MovingMesh(dom, bodies, poses, h=0.1, params=MeshParams(retriangulate_every=9), retriangulate_every=5,
                   drag_reach=2.0)
    assert a.params == b.params == c.params
    for k in range(6):
        p = poses + [0.002 * (k + 1), 0.0, 0.01 * (k + 1)]
        ea, eb = a.update(p), b.update(p)
        assert ea.reason == eb.reason
    assert np.array_equal(a.points, b.points) and np.array_equal(a.triangles, b.triangles)
    assert a.retriangulate_every == 5 and a.drag_reach == 2.0 and a.relax_iterations == 3
    assert MovingMesh(dom, bodies, poses, h=0.1, strategy="regenerate").relax_iterations == 20


@pytest.mark.parametrize("key,value,allowed", [
    ("retriangulate_every", 0, "an integer >= 1"),
    ("relax_iterations", -1, "an integer >= 0"),
    ("coarsen_ratio", 1.5, "a number in (0, 1)"),
    ("refine_area", 1.0, "a number > 1"),
    ("drag_stiffness", 2.0, "a number in [0, 1]"),
    ("clearance", 2.0, "a number in [0, 2) (multiple of h)"),
    ("min_gap", 0.0, "a positive finite number"),
    ("background", "hex", "one of 'fk', 'delaunay'"),
    ("wall_overlap_fraction", 0.6, "a number in [0, 0.5] (fraction of the body's extent)"),
    ("contact_slack", -0.1, "a number >= 0 (multiple of h)"),
])
def test_bad_values_raise_one_line_input_errors(key, value, allowed):
    with pytest.raises(InputError) as err:
        MeshParams(**{key: value})
    assert str(err.value) == f"MovingMesh({key}=...) = {value!r}: expected {allowed}"
    assert isinstance(err.value, ValueError)
    dom, bodies, poses = _scene()
    with pytest.raises(ValueError, match=key):
        MovingMesh(dom, bodies, poses, h=0.1, **{key: value})


def test_drag_full_must_stay_below_drag_reach():
    with pytest.raises(InputError, match=r"drag_full=\.\.\.\) = 3.0: expected a number in \[0, drag_reach = 2.0\)"):
        MeshParams(drag_reach=2.0, drag_full=3.0)


def test_unknown_keyword_and_strategy():
    dom, bodies, poses = _scene()
    with pytest.raises(TypeError, match="retriangulate_evry"):
        MovingMesh(dom, bodies, poses, h=0.1, retriangulate_evry=3)
    with pytest.raises(InputError, match="unknown mesh strategy 'warp': expected one of 'drag', 'regenerate'"):
        MeshParams(strategy="warp")
    with pytest.raises(InputError, match="a MeshParams"):
        MovingMesh(dom, bodies, poses, h=0.1, params={"retriangulate_every": 3})


def test_params_are_frozen():
    p = MeshParams()
    with pytest.raises(AttributeError):
        p.retriangulate_every = 3
    dom, bodies, poses = _scene()
    mm = MovingMesh(dom, bodies, poses, h=0.1)
    with pytest.raises(AttributeError, match="MovingMesh.retriangulate_every is a parameter"):
        mm.retriangulate_every = 3


def test_triangle_failure_is_a_mesh_error(monkeypatch):
    import fluidem.mesh.cutout as cutout

    real = cutout.tr.triangulate

    def adds_a_point(pslg, opts):
        out = dict(real(pslg, opts))
        out["vertices"] = np.vstack([out["vertices"], [[0.5, 0.5]]])
        return out

    monkeypatch.setattr(cutout.tr, "triangulate", adds_a_point)
    dom, bodies, poses = _scene()
    with pytest.raises(MeshError, match="outlines intersect") as err:
        MovingMesh(dom, bodies, poses, h=0.1)
    assert isinstance(err.value, RuntimeError)


def _former_state(mm):
    """The pickled state MovingMesh had before the split by stage (attribute names of then)."""
    s = dict(mm.__dict__)
    p = s.pop("params")
    for k in ("strategy", "retriangulate_every", "initial_iterations", "retriangulate_iterations",
              "min_angle_trigger", "clearance", "purge_clearance", "gap_purge", "cleanup_passes", "relax_params",
              "drag_reach", "drag_full", "drag_stiffness", "tow_width", "refine_area", "coarsen_ratio"):
        s[k] = getattr(p, k)
    s["relax_iterations"] = p.step_iterations
    s["use_junctions"] = p.junctions
    s["min_gap"] = mm.min_gap
    ol, bg, dr, base = s.pop("outlines"), s.pop("background_candidates"), s.pop("drag"), s.pop("baseline")
    s["_ol_local"], s["_ol_body"], s["_ol_next"] = ol.local, ol.body, ol.next
    s["_bg_points"], s["_bg_kind"], s["_bg_uid"] = bg.points, bg.kind, bg.uid
    s["_next_uid"] = s.pop("_uids").next
    s["ol_id"] = s.pop("outline_row")
    s["_junction_nodes"], s["_junction_verts"], s["_junction_bary"] = (
        s.pop("junction_nodes"), s.pop("junction_verts"), s.pop("junction_bary"))
    s["_drag_node"], s["_drag_body"], s["_drag_weight"], s["_relax_damping"] = dr.node, dr.body, dr.weight, \
        dr.relax_damping
    s["_cos_lo"], s["_cos_hi"], s["_base_area"], s["_base_narrow"] = base.cos_lo, base.cos_hi, base.area, base.narrow
    s["_base_cos"], s["_cos_bound"] = (base.cos_max, base.cos_min), (base.cos_bound_lo, base.cos_bound_hi)
    return s


def test_a_mesh_pickled_before_the_split_restarts_unchanged():
    """Checkpoints hold the pickled MovingMesh: one of the former layout carries on bit for bit."""
    import copy
    from dataclasses import replace

    dom, bodies, poses = _scene()
    a = MovingMesh(dom, bodies, poses, h=0.1, retriangulate_every=4)
    a.update(poses + [0.002, 0.0, 0.01])
    b = MovingMesh.__new__(MovingMesh)
    b.__setstate__(copy.deepcopy(_former_state(a)))
    # the former layout kept resolved values: the same parameters, spelled out
    assert b.params == replace(a.params, min_gap=a.min_gap, background=a.background_kind,
                               relax_iterations=a.relax_iterations)
    for k in range(8):
        p = poses + [0.002 * (k + 2), 0.0, 0.01 * (k + 2)]
        assert a.update(p).reason == b.update(p).reason
    assert np.array_equal(a.points, b.points) and np.array_equal(a.uid, b.uid)
    assert np.array_equal(a.node_velocity(0.1), b.node_velocity(0.1))
