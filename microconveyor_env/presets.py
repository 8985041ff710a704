"""Named parameter presets (YAML files in the repository's ``configs/``, shipped with the package).

``load_preset("conveyor")`` reads ``configs/conveyor.yaml``, validates it, applies its
``calibration`` block (if any) and returns a :class:`Preset`. A path to a YAML file works as well as
a name. :func:`simulator` builds a :class:`~.physics.simulator.Simulator` from a preset (the
physics layer itself takes parameters, never names).

The dissertation's two surfaces (docs/physics.md §8): ``feasibility`` (chapter 3, Table 3.1,
dgamma = 1 J/m^2) and ``conveyor`` (chapter 4, Table 4.2, dgamma = 0.5 J/m^2, calibrated on
chapter 3's surface through ``calibration.measured_with``). The former names ``dissertation``
and ``seed`` (both the chapter-3 surface) still work with a DeprecationWarning. ``ke`` is chapter
3's material with pure, uncalibrated KE; ``silicon``, ``polysilicon``, ``silicon_oxide``,
``silicon_nitride`` and ``gold`` are common MEMS surface pairs, pure KE too, with the source of
each value in their files (docs/physics.md §9).

A file's unknown key is refused with the likely key and every valid one (:func:`unknown_keys`);
a contact value it leaves out gets the default with a :class:`PresetWarning` naming it.
"""
from __future__ import annotations

import dataclasses
import functools
import warnings
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from .physics.calibration import Calibration, calibrate
from .physics.materials import ContactParams, Materials, ParameterError, Part, Surface
from .physics.simulator import Simulator

_TOP_KEYS = {"name", "description", "materials", "surface", "part", "friction_scale",
             "calibration", "dynamics"}


class PresetError(ValueError):
    """A preset that cannot be found or read."""


@dataclass(frozen=True)
class Preset:
    """A loaded preset: its name, description, (calibrated) contact parameters (SI), the
    calibration report (forces [N]; empty: nothing fitted) and its simulator defaults."""

    name: str
    description: str
    contact: ContactParams
    calibration: dict[str, Any] = field(default_factory=dict)   # what was fitted (empty: none)
    dynamics: dict[str, Any] = field(default_factory=dict)      # simulator defaults of this preset

    def forces(self) -> dict[str, float]:
        """The preset's contact figures (SI): pull-off force [N], the friction Q at the part's
        weight [N] and the slip deceleration Q(m g0) / m on a still flat surface [m/s^2]."""
        from .physics.contact_table import ContactTable

        table = ContactTable(self.contact)
        q = float(table.friction(self.contact.part.weight))
        return {"pull_off_force_N": float(table.pull_off_force), "friction_at_weight_N": q,
                "slip_deceleration_m_s2": q / self.contact.part.mass}


def available_presets() -> list[str]:
    """Names of the presets shipped with the package (sorted)."""
    files = resources.files("microconveyor_env.configs")
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".yaml"))


MAX_PRESET_BYTES = 100_000
_DYNAMICS_KEYS = {"kinematics"}  # simulator defaults a preset may set
_SECTIONS = ("materials", "surface", "part", "calibration", "dynamics")


class _NoAliasLoader(yaml.SafeLoader):
    """Safe YAML without anchors/aliases (an alias bomb would expand to gigabytes)."""

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node | None:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(None, None, "YAML aliases (*name) are not allowed "
                                              "in presets", event.start_mark)
        return super().compose_node(parent, index)


def parse_yaml(text: str, what: str) -> Any:
    """Safe-load ``text`` (no aliases, bounded size); PresetError with the position on failure;
    ``what`` names the source in messages."""
    if len(text) > MAX_PRESET_BYTES:
        raise PresetError(f"{what} is too large ({len(text)} bytes > {MAX_PRESET_BYTES})")
    try:
        return yaml.load(text, Loader=_NoAliasLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        raise PresetError(f"{what} is not valid YAML: {' '.join(str(exc).split())}") from None
    except RecursionError:
        raise PresetError(f"{what} is nested too deeply") from None


def _read(name_or_path: str) -> dict[str, Any]:
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml") and (p.exists() or p.is_symlink()):
        from .safe_files import UnsafeFileError, read_text

        try:
            text = read_text(p, MAX_PRESET_BYTES, follow_symlinks=True)
        except UnsafeFileError as exc:
            raise PresetError(f"preset {name_or_path!r} cannot be read: {exc}") from None
    else:
        res = resources.files("microconveyor_env.configs") / f"{name_or_path}.yaml"
        if "/" in str(name_or_path) or "\\" in str(name_or_path) or not res.is_file():
            import difflib

            names = available_presets()
            close = difflib.get_close_matches(str(name_or_path), names, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise PresetError(f"unknown preset {name_or_path!r}{hint}; available: "
                              f"{', '.join(names)} (or a path to a .yaml file)")
        text = res.read_text()
    data = parse_yaml(text, f"preset {name_or_path!r}")
    if not isinstance(data, dict):
        raise PresetError(f"preset {name_or_path!r} is not a YAML mapping")
    problem = unknown_keys(data, _TOP_KEYS)
    if problem:
        raise PresetError(f"preset {name_or_path!r}: {problem}")
    for key in ("name", "description"):
        if key in data and not isinstance(data[key], str):
            raise PresetError(f"preset {name_or_path!r}: {key} must be text, got "
                              f"{type(data[key]).__name__}")
    for key in _SECTIONS:
        raw = data.get(key)
        if raw is not None and not (isinstance(raw, dict) and all(isinstance(k, str) for k in raw)):
            raise PresetError(f"preset {name_or_path!r}: {key} must be a mapping of names to "
                              f"values, got {type(raw).__name__}")
    return data


def unknown_keys(given: Any, valid: Any) -> str:
    """"" if every key of ``given`` is in ``valid``, else the text naming the unknown ones, the
    likely key for each (difflib) and every valid key: ``unknown key 'dgama' (did you mean
    'dgamma'?); valid keys: beta, dgamma, ..."``."""
    valid = sorted(valid, key=str)
    unknown = sorted(set(given) - set(valid), key=str)
    if not unknown:
        return ""
    import difflib

    hints = [f"{u!r} (did you mean {close[0]!r}?)" if (close := difflib.get_close_matches(
        str(u), [str(v) for v in valid], n=1)) else repr(u) for u in unknown]
    return (f"unknown key{'s' if len(unknown) > 1 else ''} {', '.join(hints)}; "
            f"valid keys: {', '.join(str(v) for v in valid)}")


def _section(cls: type[Any], data: dict[str, Any], key: str) -> Any:
    raw = data.get(key) or {}
    problem = unknown_keys(raw, (f.name for f in dataclasses.fields(cls)))
    if problem:
        raise ParameterError(f"{key}: {problem}")
    try:
        return cls(**raw)
    except TypeError as exc:
        raise ParameterError(f"{key}: {exc}") from None


def params_from_dict(data: dict[str, Any]) -> ContactParams:
    """ContactParams from a preset mapping (sections ``materials``, ``surface``, ``part`` and
    ``friction_scale`` [-], values in SI units)."""
    return ContactParams(materials=_section(Materials, data, "materials"),
                         surface=_section(Surface, data, "surface"),
                         part=_section(Part, data, "part"),
                         friction_scale=data.get("friction_scale", 1.0))


DEFAULT_PRESET = "feasibility"
# old name -> new name (deprecated, still accepted)
RENAMED_PRESETS = {"seed": "feasibility", "dissertation": "feasibility"}


def load_preset(name_or_path: str = DEFAULT_PRESET) -> Preset:
    """Load, validate and calibrate a preset by name (:func:`available_presets`: ``feasibility``,
    ``conveyor``, ``ke``, the MEMS pairs) or YAML path."""
    name = str(name_or_path)
    if name in RENAMED_PRESETS:
        warnings.warn(f"preset {name!r} is now called {RENAMED_PRESETS[name]!r}",
                      DeprecationWarning, stacklevel=2)
        name = RENAMED_PRESETS[name]
    return _load_preset(name)


def simulator(preset: str = DEFAULT_PRESET, contact: ContactParams | None = None,
              **kw: Any) -> Simulator:
    """A :class:`Simulator` of a preset (name or YAML path): its contact parameters (or
    ``contact``, if given), its dynamics defaults (e.g. ``kinematics``), then ``kw`` (any
    Simulator argument, SI units; with ``roughness="stretch"`` also the fields of its
    :class:`~.physics.simulator.Stretch` settings, ``zone_length``, ``max_strain``,
    ``n_sigma``, which constant roughness ignores)."""
    p = load_preset(preset)
    return Simulator.from_keywords(p.contact if contact is None else contact,
                                   **{**p.dynamics, **kw})


def _calibrate(params: ContactParams, cal: dict[str, Any]) -> tuple[ContactParams, dict[str, Any]]:
    """Apply a preset's calibration block. ``measured_with`` (surface fields, SI): the surface
    the measured figures belong to; the fit runs there and its beta and friction_scale (surface
    properties) are carried to this surface."""
    measured_with = cal.pop("measured_with", None) or {}
    if not isinstance(measured_with, dict) or not set(measured_with) <= _SURFACE_FIELDS:
        raise ParameterError(f"calibration.measured_with must map surface fields "
                             f"{sorted(_SURFACE_FIELDS - {'beta'})} to values, got "
                             f"{measured_with!r}")
    if "beta" in measured_with:
        raise ParameterError("calibration.measured_with cannot set beta: beta is what the fit "
                             "carries over")
    if cal.get("friction_load") == "weight":
        cal["friction_load"] = None
    problem = unknown_keys(cal, _CALIBRATION_KEYS)  # measured_with: taken out above
    if problem:
        raise ParameterError(f"calibration: {problem}")
    target = Calibration(**cal)
    if not measured_with:
        return calibrate(params, target)
    fit_on = params.replace(**{f"surface__{k}": v for k, v in measured_with.items()})
    fitted, report = calibrate(fit_on, target)
    report["measured_with"] = dict(measured_with)
    return params.replace(surface__beta=fitted.surface.beta,
                          friction_scale=fitted.friction_scale), report


_SURFACE_FIELDS = {f.name for f in dataclasses.fields(Surface)}
_CALIBRATION_KEYS = {f.name for f in dataclasses.fields(Calibration)} | {"measured_with"}


class PresetWarning(UserWarning):
    """A preset that leaves values to the package's defaults."""


def missing_values(data: dict[str, Any]) -> list[str]:
    """The contact values a preset mapping leaves to the defaults, as ``section.key`` (and
    ``friction_scale``). A value its ``calibration`` block fits (``surface.beta`` from
    ``pull_off_force``, ``friction_scale`` from ``friction_force``) is not missing: the fit does
    not depend on its starting value."""
    cal = data.get("calibration") or {}
    fitted = ({"surface.beta"} if cal.get("pull_off_force") is not None else set()) | (
        {"friction_scale"} if cal.get("friction_force") is not None else set())
    missing = []
    for key, cls in (("materials", Materials), ("surface", Surface), ("part", Part)):
        given = data.get(key) or {}
        missing += [f"{key}.{f.name}" for f in dataclasses.fields(cls) if f.name not in given]
    if "friction_scale" not in data:
        missing.append("friction_scale")
    return [m for m in missing if m not in fitted]


def _warn_if_incomplete(name: str, data: dict[str, Any]) -> None:
    """A preset file that omits values gets the defaults of :mod:`.physics.materials` (the
    dissertation's steel pair; ``friction_scale`` 1, pure KE) for them: say which, rather than
    complete it in silence."""
    missing = missing_values(data)
    if missing:
        warnings.warn(f"preset {name!r} does not give {', '.join(missing)}: the defaults (the "
                      "dissertation's steel pair, configs/feasibility.yaml; friction_scale 1) are "
                      "used for them", PresetWarning, stacklevel=4)


@functools.lru_cache(maxsize=32)
def _load_preset(name_or_path: str) -> Preset:
    data = _read(name_or_path)
    _warn_if_incomplete(name_or_path, data)
    params = params_from_dict(data)
    report: dict[str, Any] = {}
    cal = data.get("calibration")
    if cal:
        params, report = _calibrate(params, dict(cal))
    dynamics = dict(data.get("dynamics") or {})
    problem = unknown_keys(dynamics, _DYNAMICS_KEYS)
    if problem:
        raise PresetError(f"preset {name_or_path!r}: dynamics: {problem}")
    return Preset(name=data.get("name", str(name_or_path)), description=data.get("description", ""),
                  contact=params, calibration=report, dynamics=dynamics)
