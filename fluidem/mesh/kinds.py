"""Node kinds of the moving mesh (:mod:`fluidem.mesh.nodes` describes them; the periodic
sides need them too, :mod:`fluidem.mesh.periodic`).

Examples
--------
>>> from fluidem.mesh.kinds import FREE, SIDE, CONTACT
>>> FREE, SIDE, CONTACT
(0, 1, 5)
"""

__all__ = ["FREE", "SIDE", "CORNER", "OUTLINE", "JUNCTION", "CONTACT"]

#: node kinds: free, box side (slides along it), box corner, body outline, junction, contact node
FREE, SIDE, CORNER, OUTLINE, JUNCTION, CONTACT = 0, 1, 2, 3, 4, 5
