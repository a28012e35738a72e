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
