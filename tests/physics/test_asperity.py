"""Single-asperity KE fits and derived material constants."""
import math

import numpy as np
import pytest

from microconveyor_env.physics import asperity
from microconveyor_env.physics.materials import ContactParams, Materials, Surface

K = 0.454 + 0.41 * 0.33


def test_load_fits_at_range_boundaries():
    below = lambda w: float(asperity.load(np.nextafter(w, 0), K))  # noqa: E731
    at = lambda w: float(asperity.load(w, K))  # noqa: E731
    assert below(1.0) == pytest.approx(1.0)            # onset of yield: P = P_c
    assert at(1.0) == pytest.approx(1.03)
    assert at(6.0) == pytest.approx(1.40 * 6 ** 1.263)
    assert below(6.0) == pytest.approx(1.03 * 6 ** 1.425)
    assert at(110.0) == pytest.approx(3 / K * 110)
    assert below(110.0) == pytest.approx(1.40 * 110 ** 1.263)
    # the printed fits are nearly continuous (KE 2002: within a few per cent)
    for w in (1.0, 6.0, 110.0):
        assert abs(at(w) / below(w) - 1) < 0.06
    assert at(0.0) == 0.0 and at(-1.0) == 0.0


def test_adhesion_fit_floor_and_lennard_jones_contact_value():
    k = 0.4 / 3.2
    w = np.array([1e-9, 1e-3, 0.05])
    assert np.all(asperity.adhesion_contact(w, k) == 1.0)    # floor where the fit -> 0
    assert asperity.adhesion_contact(0.5, k) == pytest.approx(0.98 * 0.5 ** 0.298 * k ** -0.29)
    assert asperity.adhesion_gap(1.0) == pytest.approx(1.0)  # LJ force at h = eps is F_s0
    for c in asperity.adhesion_floor_crossings(k):
        assert float(asperity.adhesion_contact(c * (1 + 1e-9), k)) == pytest.approx(1.0, abs=1e-6)


def test_friction_fit_ranges():
    assert float(asperity.friction(0.5)) == pytest.approx(0.52 * 0.5 ** 0.982)
    root = asperity.friction_mid_root()
    assert 3.6 < root < 4.0
    assert float(asperity.friction(root + 0.1)) == 0.0
    assert float(asperity.friction(6.5)) == 0.0
    assert np.all(asperity.friction(np.linspace(0, 10, 1001)) >= 0)


def test_composite_modulus_and_critical_interference_identity():
    m = Materials(E1=2e11, nu1=0.3, E2=1e11, nu2=0.25, hardness=2e9)
    assert m.E == pytest.approx(1 / ((1 - 0.09) / 2e11 + (1 - 0.0625) / 1e11), rel=1e-14)
    for psi in (0.5, 1.0, 2.5, 8.0):
        p = ContactParams(materials=m, surface=Surface(psi=psi))
        assert p.omega_c_star == pytest.approx(psi ** -2, rel=1e-12)
        # psi definition recovered from the derived radius
        R = p.asperity_radius
        psi_back = 2 * m.E / (math.pi * m.K * m.hardness) * math.sqrt(p.surface.sigma / R)
        assert psi_back == pytest.approx(psi, rel=1e-12)
        # Hertz at w = 1 equals the KE critical load
        hertz = 4 / 3 * m.E * math.sqrt(R) * p.critical_interference ** 1.5
        assert hertz == pytest.approx(p.critical_load, rel=1e-12)
