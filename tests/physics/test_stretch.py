"""Stretch-dependent roughness (docs/physics.md §4)."""
import numpy as np
import pytest

from microconveyor_env.physics.materials import ParameterError
from microconveyor_env.physics.stretch import StretchContact, params_at_strain


def test_params_at_strain(feasibility_preset):
    p = feasibility_preset.contact
    s = params_at_strain(p, 0.2)
    nu = p.materials.nu1
    assert s.surface.sigma == pytest.approx(p.surface.sigma * (1 - nu * 0.2))
    assert s.eta == pytest.approx(p.eta * (1 - 0.2), rel=1e-12)         # eta_n = eta (1 - e)
    assert s.asperity_radius == pytest.approx(p.asperity_radius, rel=1e-12)  # R unchanged
    with pytest.raises(ParameterError, match="strain"):
        params_at_strain(p, 1.0)


def test_pull_off_falls_for_smoother_surfaces_and_interpolates(feasibility_preset):
    sc = StretchContact(feasibility_preset.contact, max_strain=0.3, n_sigma=11, spacing=0.02)
    f = sc.pull_off_force(sc.sigmas)
    assert f[0] == pytest.approx(6.2e-6, rel=1e-9)
    assert np.all(np.diff(f) < 0)  # sigmas decrease along the grid
    err = sc.sigma_interpolation_error(np.array([-3e-6, 0.0, 2e-8, 1e-6, 1e-4]))
    assert err["max_rel_error_Q"] < 1e-3 and err["max_rel_error_pull_off"] < 1e-3
    with pytest.raises(ParameterError, match="outside the tabulated range"):
        sc.friction(0.0, 0.5 * feasibility_preset.contact.surface.sigma)
