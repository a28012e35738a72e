"""The pickled state of a :class:`~fluidem.mesh.moving.MovingMesh` written by earlier versions, in
today's attributes (checkpoints of existing runs restore).

* before the split by stage: the parameters were attributes, the outline table, background,
  drag association and quality baseline loose arrays (:func:`state_before_split`);
* before bodies could cross periodic sides: no periodic axes and no images (every body its
  own image).

Examples
--------
>>> restored_state({"params": None, "images": None})["periodic"]
()
"""

from __future__ import annotations

import numpy as np

from .drag import DragAssociation
from .nodes import BackgroundNodes, BodyOutlines, UidSource
from .params import MeshParams
from .seam import PeriodicImages
from .triggers import QualityBaseline

__all__ = ["restored_state", "state_before_split"]

#: keyword parameters stored as attributes by MovingMesh before the split by stage
_FORMER_PARAM_ATTRS = ("strategy", "retriangulate_every", "relax_iterations", "initial_iterations",
                       "retriangulate_iterations", "min_angle_trigger", "clearance", "purge_clearance", "gap_purge",
                       "cleanup_passes", "relax_params", "drag_reach", "drag_full", "drag_stiffness", "tow_width",
                       "refine_area", "coarsen_ratio")


def restored_state(state: dict) -> dict:
    """The attributes of a MovingMesh from its pickled ``state`` of any version."""
    if "params" not in state:
        state = state_before_split(state)
    state.setdefault("periodic", ())
    if "images" not in state:  # pickled before bodies could cross periodic sides
        n = state["n_bodies"]
        state.update(n_real=n, body_poses=state["poses"], _body_verts=state["_verts_local"],
                     _real_nv=state["_nv"], _real_vcat=state["_vcat"], _real_vbody=state["_vbody"],
                     _real_outlines=state["outlines"],
                     images=PeriodicImages(body=np.arange(n), cell=np.zeros((n, 2), dtype=np.int64),
                                           shift=np.zeros((n, 2))))
        nc = len(state.get("_contact_idx", ()))
        state.setdefault("_seam_outer_body", np.full(nc, -1, dtype=np.int64))
        state.setdefault("_seam_outer_local", np.zeros((nc, 2)))
    return state


def state_before_split(old: dict) -> dict:
    """The pickled state of a MovingMesh from before the split by stage, in today's attributes."""
    s = dict(old)
    kw = {k: s.pop(k) for k in _FORMER_PARAM_ATTRS}
    s["params"] = MeshParams(min_gap=s.pop("min_gap"), junctions=s.pop("use_junctions"),
                             background=s["background_kind"], **kw)
    s["outlines"] = BodyOutlines(s.pop("_ol_local"), s.pop("_ol_body"), s.pop("_ol_next"))
    s["background_candidates"] = BackgroundNodes(s.pop("_bg_points"), s.pop("_bg_kind"), s.pop("_bg_uid"))
    s["_uids"] = UidSource(s.pop("_next_uid"))
    s["outline_row"] = s.pop("ol_id")
    s["junction_nodes"] = s.pop("_junction_nodes")
    s["junction_verts"] = s.pop("_junction_verts", np.zeros((0, 3), dtype=np.int64))
    s["junction_bary"] = s.pop("_junction_bary", np.zeros((0, 3)))
    s["drag"] = DragAssociation(s.pop("_drag_node"), s.pop("_drag_body"), s.pop("_drag_weight"),
                                s.pop("_relax_damping"))
    cos_max, cos_min = s.pop("_base_cos")
    bound_lo, bound_hi = s.pop("_cos_bound")
    s["baseline"] = QualityBaseline(cos_lo=s.pop("_cos_lo"), cos_hi=s.pop("_cos_hi"), area=s.pop("_base_area"),
                                    narrow=s.pop("_base_narrow"), cos_max=cos_max, cos_min=cos_min,
                                    cos_bound_lo=bound_lo, cos_bound_hi=bound_hi)
    return s
