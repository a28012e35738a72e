"""Meshes: fixed-obstacle triangulation and the moving mesh that follows rigid bodies (paper Sec. 2–4).

Fixed obstacles: :mod:`~fluidem.mesh.triangulate` (on :mod:`~fluidem.mesh.background` size
fields).  The moving mesh, :class:`MovingMesh` (:mod:`~fluidem.mesh.moving`, parameters
:class:`MeshParams`), composes one module per pipeline stage: :mod:`~fluidem.mesh.nodes`,
:mod:`~fluidem.mesh.contact_outline`, :mod:`~fluidem.mesh.cutout` (with
:mod:`~fluidem.mesh.junctions`), :mod:`~fluidem.mesh.relax`, :mod:`~fluidem.mesh.adaptation`,
:mod:`~fluidem.mesh.drag`, :mod:`~fluidem.mesh.gaps` and :mod:`~fluidem.mesh.triggers`, through
functions over its state by concern (:mod:`~fluidem.mesh.moving_triangulation`,
:mod:`~fluidem.mesh.drag_step`, :mod:`~fluidem.mesh.moving_images`,
:mod:`~fluidem.mesh.moving_history`, :mod:`~fluidem.mesh.moving_input`,
:mod:`~fluidem.mesh.moving_state`); :mod:`~fluidem.mesh.quality` measures it and
:mod:`~fluidem.mesh.transfer` carries fields across re-triangulations.
"""

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
