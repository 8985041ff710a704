"""The ``microconveyor`` command line.

Every subcommand accepts ``--json`` and then prints exactly one JSON object on stdout (SI units, keys
with unit suffixes); human-readable text and progress bars go to stderr. Every error (a bad
argument included) exits with status 2 and one line on stderr and, under ``--json``, prints one
``{"error": ..., "error_type": ...}`` object on stdout; never a traceback.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
import traceback

from .physics.materials import ParameterError

COMMANDS: dict = {}


def command(name, help_):
    def deco(fn):
        COMMANDS[name] = (fn, help_)
        return fn
    return deco


def _emit(args, result: dict, human: str = "") -> None:
    if args.json:
        print(json.dumps(result, indent=None, default=_json_default, allow_nan=False))
    else:
        print(human or "\n".join(f"{k:32s} {v}" for k, v in result.items()))


def _json_default(o):
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


# ----------------------------------------------------------------------------- value parsing
def _plot_path(text: str) -> str:
    """``--plot`` value: a non-empty file name; without an extension ``.png`` is added (the
    reported path is the one written); the extension must be a format matplotlib writes."""
    from pathlib import Path

    if not text.strip():
        raise argparse.ArgumentTypeError("empty file name")
    path = Path(text)
    if text.endswith(("/", "\\")) or path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a folder; give a file name")
    if not path.suffix:
        path = path.with_name(path.name + ".png")
    fmt = path.suffix[1:].lower()
    if fmt not in _plot_formats():
        raise argparse.ArgumentTypeError(f"unsupported chart format {fmt!r}; use one of "
                                         f"{', '.join(sorted(_plot_formats()))}")
    return str(path)


def _plot_formats() -> set:
    from matplotlib.backend_bases import FigureCanvasBase

    return set(FigureCanvasBase.get_supported_filetypes())


def _count(lo: int, hi: int | None = None):
    """An integer option in [lo, hi] (hi None: the library checks the upper bound)."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if v < lo or (hi is not None and v > hi):
            raise argparse.ArgumentTypeError(f"must be an integer in [{lo}, "
                                             f"{'...' if hi is None else f'{hi:g}'}], got {v}")
        return v
    return parse


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--preset", default="seed", help="preset name (seed, ke) or YAML path")


# ----------------------------------------------------------------------------- contact
def _contact_args(p):
    p.add_argument("--plot", metavar="FILE.png", type=_plot_path,
                   help="draw P, F_s, N and Q versus separation")
    p.add_argument("--check-table", action="store_true",
                   help="also measure the table against direct quadrature")


@command("contact", "contact report of a preset (pull-off, friction at weight, separations)")
def cmd_contact(args):
    from .physics.contact_table import ContactTable, tabulation_error
    from .presets import load_preset

    preset = load_preset(args.preset)
    t0 = time.perf_counter()
    table = ContactTable(preset.contact)
    out = {"preset": preset.name, **table.report(),
           "table_build_s": table.base.build_seconds,
           "table_load_s": time.perf_counter() - t0,
           "calibration": preset.calibration}
    if args.check_table:
        out["table_error"] = tabulation_error(table)
    if args.plot:
        from .plots import plot_contact

        out["plot"] = str(plot_contact(table, args.plot, f"preset {preset.name}"))
    _emit(args, out)


# ----------------------------------------------------------------------------- demo
def _demo_args(p):
    p.add_argument("--out", default="out", help="output folder for charts and the summary JSON")


@command("demo", "the main job: contact report, a firing, a frequency sweep and an env episode, "
                 "charts written to --out")
def cmd_demo(args):
    from pathlib import Path

    from .physics.contact_table import ContactTable
    from .plots import plot_contact, plot_firing, plot_sweep
    from .presets import load_preset
    from .studies.sweep import Scene, parse_values, sweep

    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    preset = load_preset(args.preset)
    table = ContactTable(preset.contact)
    charts = [plot_contact(table, out_dir / "contact.png", f"preset {preset.name}")]
    scene = Scene(preset=args.preset)
    # the chart's firing with a 10x finer step than the default, so the curves are smooth; run
    # once first so the reported wall time is the steady-state figure, not the numba compile
    fine = Scene(preset=args.preset, sim_kw={"dt": 5e-6})
    fine.run()
    firing = fine.run(record=True)
    charts.append(plot_firing(firing, scene.freq, out_dir / "firing.png", stroke=scene.stroke))
    freq = sweep(scene, "freq", parse_values("200:1500:25", "freq"), progress=True)
    charts.append(plot_sweep(freq, out_dir / "sweep.png"))
    episode = _demo_episode(out_dir / "episode.png")
    charts.append(episode.pop("chart"))
    summary = {"preset": preset.name, "contact": table.report(), "calibration": preset.calibration,
               "seed_firing": firing.to_dict(), "window_hz": freq["window_hz"],
               "max_travel_m": freq.get("max_travel_m"), "episode": episode,
               "charts": [str(c) for c in charts]}
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2, default=_json_default))
    summary["summary_json"] = str(out_dir / "summary.json")
    _emit(args, summary, "\n".join(f"wrote {c}" for c in summary["charts"] + [summary["summary_json"]]))


def _demo_episode(path):
    """One MicroConveyor-v0 episode with a constant action (950 Hz, 200 um, no delay), rendered."""
    import gymnasium as gym

    from .envs import actions
    from .plots import save_frames

    env = gym.make("MicroConveyor-v0", render_mode="rgb_array")
    env.reset(seed=0, options={"target": 1e-3})
    action = actions.encode_actions(950.0, 200e-6, 0.0, env.unwrapped.config)
    frames, total = [env.render()], 0.0
    while True:
        _, r, term, trunc, info = env.step(action)
        total += r
        frames.append(env.render())
        if term or trunc:
            break
    return {"chart": save_frames(frames, path), "return": total, **info}


# ----------------------------------------------------------------------------- simulation
def _scene_args(p, sweep=False):
    num = str if sweep else float
    p.add_argument("--freq", type=num, default=None if sweep else 950.0,
                   help="stroke frequency f [Hz] (stroke lasts 1/f)")
    p.add_argument("--stroke", type=num, default=None if sweep else 200e-6, help="stroke height h [m]")
    p.add_argument("--x0", type=num, default=None if sweep else 0.125e-3,
                   help="start position [m] (actuator at 0)")
    p.add_argument("--wavelength", type=num, default=None if sweep else 0.6e-3,
                   help="deformation wavelength WL [m]")
    p.add_argument("--profile", default=None if sweep else "gaussian",
                   help="shape: gaussian, sinusoidal, clamped_beam")
    if sweep:
        for name in ("mass", "sigma", "dgamma"):
            p.add_argument(f"--{name}", default=None, help=f"sweep {name} (SI units)")
    p.add_argument("--mode", default="event", choices=("event", "karnopp"))
    p.add_argument("--kinematics", default="seed", choices=("seed", "exact"))
    p.add_argument("--roughness", default="constant", choices=("constant", "stretch"),
                   help="stretch: sigma follows the strain of the active zone (physics.md §4)")
    p.add_argument("--dt", type=float, default=None, help="largest RK4 step [s]")
    p.add_argument("--max-steps", type=_count(1), default=None,
                   help="refuse a firing needing more RK4 steps (default 1e7; raise it if you "
                        "mean it)")
    p.add_argument("--plot", metavar="FILE.png", type=_plot_path, help="write a chart")


def _sim_kw(args) -> dict:
    kw = {"mode": args.mode, "kinematics": args.kinematics}
    if args.dt is not None:
        kw["dt"] = args.dt
    if args.roughness != "constant":
        kw["roughness"] = args.roughness
    if args.max_steps is not None:
        kw["max_steps"] = args.max_steps
    return kw


@command("simulate", "one firing of one actuator: travel, outcome, timing")
def cmd_simulate(args):
    from .studies.sweep import Scene

    scene = Scene(preset=args.preset, freq=args.freq, stroke=args.stroke, x0=args.x0,
                  wavelength=args.wavelength, profile=args.profile, sim_kw=_sim_kw(args))
    sim = scene.simulator()
    scene.run()  # load the compiled kernel first, so wall_time_s is the steady-state figure
    res = scene.run(record=bool(args.plot))
    out = {"preset": args.preset, "freq_hz": args.freq, "stroke_m": args.stroke, "x0_m": args.x0,
           "profile": args.profile, "mode": args.mode, "kinematics": args.kinematics,
           "dt_s": sim.dt, "steps_per_stroke": sim.steps_per_stroke(args.freq),
           **res.to_dict(), "rest_time_s": res.rest_time_s}
    if args.plot:
        from .plots import plot_firing

        out["plot"] = str(plot_firing(res, args.freq, args.plot, stroke=args.stroke))
    _emit(args, out)


@command("sweep", "travel versus one parameter (frequency by default) and the feasible window")
def cmd_sweep(args):
    from .studies.sweep import SWEEPABLE, Scene, parse_values, sweep

    given = {k: getattr(args, k) for k in SWEEPABLE if getattr(args, k, None) is not None}
    swept = [k for k, v in given.items() if k != "profile" and (":" in v or "," in v)]
    if "profile" in given and "," in given["profile"]:
        swept.append("profile")
    if len(swept) != 1:
        raise ValueError(f"give exactly one swept parameter as start:stop:step or a list "
                         f"(got {swept or 'none'}); e.g. --freq 200:1500:25")
    param = swept[0]
    base = {}
    for k, v in given.items():
        if k != param:
            base[k] = v if k == "profile" else parse_values(v, k, 1)[0]
    scene = Scene(preset=args.preset, sim_kw=_sim_kw(args), **base)
    limit = {} if args.max_points is None else {"max_points": args.max_points}
    values = parse_values(given[param], param, **limit)
    res = sweep(scene, param, values, progress=not args.no_progress, **limit)
    keyed = {"freq": "freq_hz", "stroke": "stroke_m", "x0": "x0_m", "wavelength": "wavelength_m",
             "mass": "mass_kg", "sigma": "sigma_m", "dgamma": "dgamma_J_m2", "profile": "profile"}
    out = {"preset": args.preset,
           **{keyed[k]: getattr(scene, k) for k in SWEEPABLE if k != param}, **res}
    if args.plot:
        from .plots import plot_sweep

        out["plot"] = str(plot_sweep(res, args.plot))
    _emit(args, out, _sweep_text(res))


def _sweep_text(res) -> str:
    lines = [f"{res['param']:>12s}  travel [um]  outcome"]
    for v, d, o in zip(res["values"], res["displacement_m"], res["outcome"]):
        lines.append(f"{v!s:>12s}  {d * 1e6:11.2f}  {o}")
    if res.get("window") is not None:
        lines.append(f"feasible window: {res['window']} {res['unit']}")
    return "\n".join(lines)


def _sweep_args(p):
    _scene_args(p, sweep=True)
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.add_argument("--max-points", type=_count(1, 10 ** 9), default=None,
                   help="refuse sweeps of more points (default 10000; raise it if you mean it)")


@command("accuracy", "speed versus accuracy of the integrator settings (chart + default choice)")
def cmd_accuracy(args):
    if args.episode:
        return _accuracy_episode(args)
    from .studies.accuracy import accuracy_study

    study = accuracy_study(args.preset, repeats=args.repeats, progress=True)
    if args.plot:
        from .plots import plot_accuracy

        study["plot"] = str(plot_accuracy(study, args.plot))
    d = study["default"]
    _emit(args, study, f"default: {d}" if d else "no setting within tolerance")


def _accuracy_episode(args):
    from .studies.episodes import episode_study

    if args.preset != "seed":
        raise ValueError("--episode runs MicroConveyor-v0's own preset (seed); drop --preset")
    study = episode_study(n_per_category=args.per_category, seed=args.seed,
                          repeats=min(args.repeats, 5), progress=True)
    if args.plot:
        from .plots import plot_episode_accuracy

        study["plot"] = str(plot_episode_accuracy(study, args.plot))
    _emit(args, study, _episode_text(study))


def _episode_text(study) -> str:
    lines = [f"{study['episodes']} episodes {study['counts']}, reference event dt = "
             f"{study['reference_dt_s']:g} s (halving it moves no final position by more than "
             f"{study['reference_half_dt_check']['max_error_m']:.1e} m)",
             f"{'mode':>8} {'dt [s]':>9} {'min':>4} {'median':>9} {'p95':>9} {'max':>9} "
             f"{'outc.':>5} {'succ.':>5} {'steps':>6} {'us/ep':>7}"]
    for r in study["rows"]:
        lines.append(f"{r['mode']:>8} {r['dt_s']:9.3g} {r['min_steps']:4d} "
                     f"{r['median_error_m']:9.2e} {r['p95_error_m']:9.2e} {r['max_error_m']:9.2e} "
                     f"{r['outcome_disagreements']:5d} {r['success_disagreements']:5d} "
                     f"{r['rk4_steps_per_episode']:6.0f} "
                     f"{r['wall_per_episode_s'] * 1e6:7.1f}")
    rec = study["recommended"]
    lines.append("recommended default: " + (f"{rec['mode']}, dt = {rec['dt_s']:g} s, min_steps = "
                                            f"{rec['min_steps']}" if rec else "none meets the bar"))
    return "\n".join(lines)


def _accuracy_args(p):
    p.add_argument("--plot", metavar="FILE.png", type=_plot_path, help="write the chart")
    p.add_argument("--repeats", type=_count(1, 10_000), default=30,
                   help="timed repeats per setting")
    p.add_argument("--episode", action="store_true",
                   help="whole MicroConveyor-v0 episodes (final position and outcome) instead of "
                        "the single seed firing")
    p.add_argument("--per-category", type=_count(1, 10_000), default=60,
                   help="--episode: episodes per category (4 categories)")
    p.add_argument("--seed", type=int, default=0, help="--episode: seed of the episode set")


@command("bench", "kernel speed on the seed firing, against the dissertation-style loop")
def cmd_bench(args):
    from .studies.bench import bench_modes

    out = {"modes": bench_modes(args.preset, repeats=args.repeats)}
    if args.skip_reference:
        out["reference"] = None
        out["reference_note"] = "skipped"
    else:
        from .presets import load_preset
        from .studies.reference_loop import converged_dt

        contact = load_preset(args.preset).contact
        ref = converged_dt(contact)
        out["reference"] = ref
        default = out["modes"]["event"]["median_wall_time_s"]
        out["speedup_vs_reference"] = ref["wall_time_s"] / default
    _emit(args, out)


def _bench_args(p):
    p.add_argument("--repeats", type=_count(1, 1_000_000), default=500,
                   help="timed repeats per mode")
    p.add_argument("--skip-reference", action="store_true",
                   help="do not run the (slow) plain-Python reference")


_ARGS = {"contact": _contact_args, "demo": _demo_args, "simulate": _scene_args,
         "sweep": _sweep_args, "accuracy": _accuracy_args, "bench": _bench_args}

from .studies.cli_studies import register as _register_studies  # noqa: E402  (studies: issue #9)

_register_studies(command, _ARGS, _emit)


class UsageError(ValueError):
    """A command line argparse refused (raised instead of printing usage and exiting)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(f"{self.prog}: {message} (see --help)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="microconveyor", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name, (fn, help_) in COMMANDS.items():
        p = sub.add_parser(name, help=help_, description=help_)
        _common(p)
        _ARGS.get(name, lambda _p: None)(p)
        p.set_defaults(func=fn)
    return parser


# Errors that user input can cause: reported in one line, never with a traceback.
USER_ERRORS = (ParameterError, ValueError, RuntimeError, OSError, OverflowError, MemoryError,
               RecursionError)


def _fail(argv, command: str, exc: BaseException) -> int:
    """The error contract: ``--json``: one ``{"error": ...}`` object on stdout; always one line on
    stderr; exit status 2."""
    expected = isinstance(exc, USER_ERRORS)
    text = " ".join(str(exc).split()) or type(exc).__name__  # one line
    if not expected:
        text += " (internal error: please report it; MICROCONVEYOR_DEBUG=1 shows the traceback)"
    msg = f"{type(exc).__name__}: {text}"
    if any(a.startswith("--j") and "--json".startswith(a) for a in argv):  # argparse abbrevs
        print(json.dumps({"error": msg, "error_type": type(exc).__name__}), flush=True)
    print(f"microconveyor{' ' + command if command else ''}: {msg}", file=sys.stderr)
    if not expected and os.environ.get("MICROCONVEYOR_DEBUG"):
        traceback.print_exception(exc)
    return 2


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    command = ""
    try:
        args = build_parser().parse_args(argv)
        command = args.command
        args.func(args)
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # noqa: BLE001 - the error contract covers every failure
        return _fail(argv, command, exc)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
