"""Meshes: fixed-obstacle triangulation and the moving mesh that follows rigid bodies (paper Sec. 2–4)."""

from .moving import STRATEGIES, MeshEvent, MovingMesh
from .params import MeshParams
from .quality import MeshQuality, OscillationDetector, mesh_quality, triangle_angles
from .relax import RelaxParams, mesh_topology, relax
from .transfer import interpolate, project_l2, supermesh

__all__ = [
    "MovingMesh",
    "MeshEvent",
    "STRATEGIES",
    "MeshParams",
    "MeshQuality",
    "OscillationDetector",
    "mesh_quality",
    "triangle_angles",
    "RelaxParams",
    "mesh_topology",
    "relax",
    "interpolate",
    "project_l2",
    "supermesh",
]
