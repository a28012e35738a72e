"""The fast re-assembly reproduces scikit-fem's assembly of the same forms."""

import numpy as np
import pytest
from skfem import asm

from fluidem.cases.dfg import dfg_mesh
from fluidem.fluid import forms
from fluidem.fluid.assembly import VectorAssembler
from fluidem.fluid.space import FlowSpace


@pytest.mark.parametrize("element, curved", [("p2b", True), ("th", False), ("mini", False), ("p3", True)])
def test_convection_matches_skfem(element, curved):
    space = FlowSpace(dfg_mesh(0, curved=curved), element)
    ub = space.ub
    rng = np.random.default_rng(1)
    a, b = rng.standard_normal(ub.N), rng.standard_normal(ub.N)
    va = VectorAssembler(ub)
    ref = asm(forms.convection, ub, b=ub.interpolate(b)) + asm(forms.convection_newton, ub, a=ub.interpolate(a))
    got = va.matrix(va.convection(b, a))
    assert abs(got - ref).max() < 1e-12 * abs(ref).max()
    ref_v = asm(forms.convection_residual, ub, a=ub.interpolate(a), b=ub.interpolate(b))
    np.testing.assert_allclose(va.convection_vector(a, b), ref_v, atol=1e-12 * np.abs(ref_v).max())


@pytest.mark.parametrize("element, curved", [("p2b", True), ("th", False), ("mini", False), ("p3", True)])
def test_constant_forms_match_skfem(element, curved):
    """The pattern refill of the moving mesh: viscous (both forms), mass and divergence as scikit-fem assembles them."""
    from fluidem.fluid.assembly import DivergencePattern

    space = FlowSpace(dfg_mesh(0, curved=curved), element)
    ub, pb = space.ub, space.pb
    va = VectorAssembler(ub)
    for form, data in ((forms.viscous, va.viscous_data()), (forms.viscous_stress, va.stress_data()),
                       (forms.mass, va.mass_data())):
        ref = asm(form, ub)
        assert abs(va.matrix(data) - ref).max() < 1e-12 * abs(ref).max()
    ref = asm(forms.divergence, ub, pb)
    assert abs(DivergencePattern(va, pb).matrix(pb) - ref).max() < 1e-12 * abs(ref).max()


@pytest.mark.parametrize("element, curved", [("p2b", True), ("th", False), ("mini", False), ("p3", True)])
def test_divergence_mass_matches_skfem_and_completes_the_divergence_form(element, curved):
    """(div c) u·v as scikit-fem assembles it; with the convection it is div(u ⊗ c)·v, whose
    integral against a constant v is the boundary flux of c: zero for a c that vanishes on the
    boundary (measured 1.3e-17 to 3.4e-16 of the terms, round-off)."""
    from skfem import BilinearForm

    @BilinearForm
    def div_mass(u, v, w):
        return (w["c"].grad[0][0] + w["c"].grad[1][1]) * (u[0] * v[0] + u[1] * v[1])

    space = FlowSpace(dfg_mesh(0, curved=curved), element)
    ub = space.ub
    rng = np.random.default_rng(2)
    a, c = rng.standard_normal(ub.N), rng.standard_normal(ub.N)
    va = VectorAssembler(ub)
    ref = asm(div_mass, ub, c=ub.interpolate(c))
    assert abs(va.matrix(va.divergence_mass(c)) - ref).max() < 1e-12 * abs(ref).max()
    np.testing.assert_allclose(va.divergence_mass_vector(c, a), ref @ a, atol=1e-12 * np.abs(ref @ a).max())
    c[ub.get_dofs().all()] = 0.0  # no flux through the boundary
    e_x = ub.project(lambda x: np.array([np.ones_like(x[0]), np.zeros_like(x[0])]))
    total = e_x @ (va.convection_vector(a, c) + va.divergence_mass_vector(c, a))
    scale = np.abs(e_x) @ np.abs(va.convection_vector(a, c))
    assert abs(total) < 1e-15 * scale, abs(total) / scale
