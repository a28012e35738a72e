"""Incompressible flow on fixed or moving (ALE) triangle meshes: elements, forms, solvers, forces."""
