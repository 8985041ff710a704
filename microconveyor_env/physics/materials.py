"""Validated parameter sets for the contact model (SI units throughout).

Three small frozen dataclasses hold what the Kogut–Etsion (KE) model needs:

* :class:`Materials` -- elastic constants of the two bodies and the hardness of the softer one;
* :class:`Surface`   -- roughness statistics and adhesion (sigma, psi, beta, dgamma, eps);
* :class:`Part`      -- the micropart (mass and nominal contact area).

:class:`ContactParams` bundles them with a dimensionless friction calibration scale and derives the
quantities of docs/physics.md §2.1 (composite modulus, K, asperity radius, critical
interference, ...).
Every field is checked on construction; an invalid value raises :class:`ParameterError` naming the
field, its value and the allowed range. Most ranges are those where the contact table can be built
(scanned one field at a time around the seed material; e.g. more surface energy than 2 J/m^2
leaves no stable branch up to the table's load range). Two bounds say why they are where they are
(docs/physics.md §2.1, "Validity"):

* ``Surface.sigma >= 1 nm`` is physical: a smoother surface is a few interatomic distances high,
  within ~2 ``eps`` of flat, and no longer a population of continuum asperities
  (Greenwood & Williamson 1966; Kogut & Etsion 2002-2004 build on that picture);
* ``Surface.psi >= 0.1`` is numerical: the KE model itself tends to the elastic
  Greenwood–Williamson model as psi -> 0, but below 0.1 the tables are not verified (asperity radii
  of tens of um to mm on nm-rough surfaces).

:class:`ContactParams` also refuses an asperity radius smaller than ``sigma`` (a psi above
``2E/(pi K H)``): KE's single-asperity laws are finite-element results for a sphere whose
interference stays small against its radius (Kogut & Etsion 2002). A combination of in-range
values can still fall outside the model; building its table then raises a
:class:`ParameterError` listing all the contact fields.
"""
from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass, field
from typing import Any

G0 = 9.81
"""Gravitational acceleration [m/s^2]."""


class ParameterError(ValueError):
    """An invalid physical parameter (message names the field, its value and the allowed range)."""


def check_range(owner: str, name: str, value: object, lo: float = -math.inf, hi: float = math.inf,
                lo_open: bool = False, hi_open: bool = False, unit: str = "",
                why_low: str = "") -> float:
    """Return ``float(value)`` or raise :class:`ParameterError` if it is not a finite real number
    in range (bools and numeric strings are refused, not converted). ``lo``, ``hi`` are in the
    value's own unit, named by ``unit`` for the message; ``owner.name`` labels the field;
    ``why_low`` (if given) ends the message of a value below ``lo`` with the reason for that bound."""
    label = f"{owner}.{name}" if owner else name
    lb = "(" if lo_open else "["
    rb = ")" if hi_open else "]"
    allowed = f"a finite number in {lb}{lo:g}, {hi:g}{rb}" + (f" [{unit}]" if unit else "")
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        hint = ""
        if isinstance(value, str):
            hint = (" (a number, not text; note that YAML reads 1e-3 without a decimal point as "
                    "text: write 1.0e-3)")
        raise ParameterError(f"{label} = {value!r} is invalid: must be {allowed}{hint}")
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(f"{label} = {value!r} is invalid: must be {allowed}") from None
    bad = (not math.isfinite(v) or v < lo or v > hi or (lo_open and v == lo)
           or (hi_open and v == hi))
    if bad:
        low = why_low if why_low and (v < lo or (lo_open and v == lo)) else ""
        raise ParameterError(f"{label} = {value!r} is invalid: must be {allowed}"
                             + (f": {low}" if low else ""))
    return v


def _validate(obj: object, specs: dict[str, tuple[float, float, bool, bool, str]],
              why_low: dict[str, str] | None = None) -> None:
    for name, (lo, hi, lo_open, hi_open, unit) in specs.items():
        v = check_range(type(obj).__name__, name, getattr(obj, name), lo, hi, lo_open, hi_open, unit,
                        (why_low or {}).get(name, ""))
        object.__setattr__(obj, name, v)


SIGMA_MIN = 1e-9
"""Smallest roughness [m] the model describes (physical bound, docs/physics.md §2.1)."""
PSI_MIN = 0.1
"""Smallest plasticity index [-] with verified contact tables (numerical bound)."""
_WHY_SIGMA = ("a surface smoother than 1 nm rms is a few interatomic distances high, within ~2 eps "
              "(the Lennard-Jones distance, ~0.4 nm) of flat: it is no longer a Gaussian population "
              "of continuum spherical asperities, the picture of Greenwood & Williamson (1966) on "
              "which the Kogut–Etsion model (Kogut & Etsion 2002, 2003, 2004) is built "
              "(docs/physics.md §2.1)")
_WHY_PSI = ("a numerical bound, not one of the KE model (which tends to the elastic "
            "Greenwood–Williamson model as psi -> 0): below psi = 0.1 the asperity radius is tens "
            "of um to mm on nm-rough surfaces and the contact tables are not verified "
            "(docs/physics.md §2.1)")


@dataclass(frozen=True)
class Materials:
    """Elastic properties of the carrier surface (body 1) and the part (body 2).

    Attributes
    ----------
    E1, E2 : Young's moduli [Pa], in [1e8, 1e13].
    nu1, nu2 : Poisson ratios [-], in [0, 0.5). ``nu1`` also sets the KE factor ``K = 0.454 + 0.41 nu1``
        and the Poisson thinning of the stretched carrier (docs/physics.md §4).
    hardness : hardness of the softer body [Pa], in [1e9, 1e11] (200 HB ~ 1.96e9 Pa).
    """

    E1: float = 2e11
    nu1: float = 0.33
    E2: float = 2e11
    nu2: float = 0.33
    hardness: float = 1.96e9

    def __post_init__(self) -> None:
        _validate(self, {
            "E1": (1e8, 1e13, False, False, "Pa"), "E2": (1e8, 1e13, False, False, "Pa"),
            "nu1": (0, 0.5, False, True, "-"), "nu2": (0, 0.5, False, True, "-"),
            "hardness": (1e9, 1e11, False, False, "Pa"),
        })

    @property
    def E(self) -> float:
        """Composite modulus ``1/E = (1-nu1^2)/E1 + (1-nu2^2)/E2`` [Pa]."""
        # squares by multiplication, not pow(): libm's pow may differ in the last bit between CPUs
        return 1.0 / ((1 - self.nu1 * self.nu1) / self.E1 + (1 - self.nu2 * self.nu2) / self.E2)

    @property
    def K(self) -> float:
        """Hardness coefficient ``K = 0.454 + 0.41 nu1`` [-]."""
        return 0.454 + 0.41 * self.nu1


@dataclass(frozen=True)
class Surface:
    """Rough-surface statistics and adhesion.

    Attributes
    ----------
    sigma : standard deviation of asperity heights [m], in [1e-9, 1e-6] (smoother than 1 nm is
        outside the asperity model; see the module docstring).
    psi : plasticity index [-], in [0.1, 1e3] (the lower bound is numerical); fixes the asperity
        radius R, which must not be smaller than sigma (checked by :class:`ContactParams`).
    beta : ``eta R sigma`` [-], in [1e-6, 1e3]; fixes the asperity density eta.
    dgamma : surface energy (work of adhesion per area) [J/m^2], in [1e-6, 2] (the model needs
        adhesion: without it there is no pull-off point and no stable branch to tabulate).
    eps : Lennard-Jones intermolecular distance [m], in [1e-10, 3e-9] (about 0.4 nm).
    """

    sigma: float = 20e-9
    psi: float = 2.5
    beta: float = 0.04
    dgamma: float = 1.0
    eps: float = 0.4e-9

    def __post_init__(self) -> None:
        _validate(self, {
            "sigma": (SIGMA_MIN, 1e-6, False, False, "m"), "psi": (PSI_MIN, 1e3, False, False, "-"),
            "beta": (1e-6, 1e3, False, False, "-"), "dgamma": (1e-6, 2.0, False, False, "J/m^2"),
            "eps": (1e-10, 3e-9, False, False, "m"),
        }, why_low={"sigma": _WHY_SIGMA, "psi": _WHY_PSI})


@dataclass(frozen=True)
class Part:
    """The micropart.

    Attributes
    ----------
    mass : [kg], in [1e-15, 1] (default 2e-9 kg, a ~100 um steel cube); its weight must also be
        within the contact table (checked with the table).
    area : nominal contact area A_n [m^2], in [1e-14, 1] (default 100 um x 100 um).
    """

    mass: float = 2e-9
    area: float = 1e-8

    def __post_init__(self) -> None:
        _validate(self, {"mass": (1e-15, 1.0, False, False, "kg"),
                         "area": (1e-14, 1.0, False, False, "m^2")})

    @property
    def weight(self) -> float:
        """``m g0`` [N]."""
        return self.mass * G0


@dataclass(frozen=True)
class ContactParams:
    """Everything the KE contact table depends on.

    ``friction_scale`` [-] (in [1e-6, 1e6]) multiplies the KE static-friction force Q; it is the friction
    calibration of docs/physics.md §2.6 (1 = pure KE).
    """

    materials: Materials = field(default_factory=Materials)
    surface: Surface = field(default_factory=Surface)
    part: Part = field(default_factory=Part)
    friction_scale: float = 1.0

    def __post_init__(self) -> None:
        for name, cls in (("materials", Materials), ("surface", Surface), ("part", Part)):
            if not isinstance(getattr(self, name), cls):
                raise ParameterError(f"ContactParams.{name} must be a {cls.__name__}, "
                                     f"got {type(getattr(self, name)).__name__}")
        _validate(self, {"friction_scale": (1e-6, 1e6, False, False, "-")})
        self._check_asperity_radius()

    def _check_asperity_radius(self) -> None:
        """ParameterError if the asperity radius R [m] is smaller than sigma [m] (psi above
        ``2E/(pi K H)``): outside the single-asperity laws of Kogut & Etsion (2002)."""
        m, s = self.materials, self.surface
        if self.asperity_radius >= s.sigma:
            return
        psi_max = 2 * m.E / (math.pi * m.K * m.hardness)
        raise ParameterError(
            f"Surface.psi = {s.psi!r} is outside the Kogut–Etsion model for these materials: with "
            f"Surface.sigma = {s.sigma:g} m, Materials.E1 = {m.E1:g} Pa, Materials.nu1 = {m.nu1:g}, "
            f"Materials.E2 = {m.E2:g} Pa, Materials.nu2 = {m.nu2:g} and Materials.hardness = "
            f"{m.hardness:g} Pa it gives an asperity radius R = {self.asperity_radius:.3g} m, "
            f"smaller than sigma. KE's single-asperity laws are finite-element results for a "
            f"sphere pressed by small interferences compared with its radius (Kogut & Etsion 2002, "
            f"J. Appl. Mech. 69: 657-662), while asperities here are pressed by ~sigma: psi must "
            f"be at most 2E/(pi K H) = {psi_max:.3g} (R >= sigma; docs/physics.md §2.1)")

    # ---- derived quantities (docs/physics.md §2.1) ----
    @property
    def asperity_radius(self) -> float:
        """R from ``psi = (2E/(pi K H)) sqrt(sigma/R)`` [m]."""
        m, s = self.materials, self.surface
        r = 2 * m.E / (math.pi * m.K * m.hardness * s.psi)
        return s.sigma * (r * r)

    @property
    def critical_interference(self) -> float:
        """``omega_c = (pi K H / (2E))^2 R`` [m] (equals sigma / psi^2)."""
        m = self.materials
        r = math.pi * m.K * m.hardness / (2 * m.E)
        return (r * r) * self.asperity_radius

    @property
    def omega_c_star(self) -> float:
        """``omega_c / sigma`` [-]."""
        return self.critical_interference / self.surface.sigma

    @property
    def eta(self) -> float:
        """Asperity areal density ``beta / (R sigma)`` [1/m^2]."""
        return self.surface.beta / (self.asperity_radius * self.surface.sigma)

    @property
    def critical_load(self) -> float:
        """Single-asperity critical load ``P_c = (2/3) pi K H R omega_c`` [N]."""
        m = self.materials
        return (2.0 / 3.0) * math.pi * m.K * m.hardness * self.asperity_radius * self.critical_interference

    @property
    def adhesion_force_scale(self) -> float:
        """Single-asperity pull-off ``F_s0 = 2 pi dgamma R`` [N]."""
        return 2 * math.pi * self.surface.dgamma * self.asperity_radius

    @property
    def asperity_count(self) -> float:
        """``eta A_n``: number of asperities on the nominal area [-]."""
        return self.eta * self.part.area

    def replace(self, **changes: Any) -> ContactParams:
        """Copy with top-level fields or ``surface__sigma=...``-style nested fields changed (each in
        its field's SI unit)."""
        nested: dict[str, dict[str, Any]] = {}
        top: dict[str, Any] = {}
        for k, v in changes.items():
            if "__" in k:
                group, name = k.split("__", 1)
                nested.setdefault(group, {})[name] = v
            else:
                top[k] = v
        for group, kv in nested.items():
            if group not in ("materials", "surface", "part"):
                raise ParameterError(f"unknown parameter group {group!r}")
            top[group] = dataclasses.replace(top.get(group, getattr(self, group)), **kv)
        return dataclasses.replace(self, **top)

    def as_dict(self) -> dict[str, Any]:
        """Plain nested dict of the inputs (stable key order; used for cache hashing)."""
        return dataclasses.asdict(self)
