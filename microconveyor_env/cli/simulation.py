"""``microconveyor simulate | sweep | accuracy | bench``: one firing, sweeps, the accuracy studies
and the kernel benchmark."""
from __future__ import annotations

import argparse
from typing import Any

from .base import command, count, emit, plot_path, preset_arg


# what ``sweep`` sweeps when no parameter is given as a range or list: the frequency [Hz]
DEFAULT_SWEEP = ("freq", "200:1500:25")


def _scene_args(p: argparse.ArgumentParser, sweep: bool = False) -> None:
    preset_arg(p)
    num = str if sweep else float
    p.add_argument("--freq", type=num, default=None if sweep else 950.0,
                   help="stroke frequency f [Hz] (stroke lasts 1/f)" + (
                       f"; swept over {DEFAULT_SWEEP[1]} when no parameter is given as "
                       "start:stop:step or a list" if sweep else ""))
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
    p.add_argument("--kinematics", default="reduced", choices=("reduced", "exact", "seed"),
                   help="reduced (the dissertation's model) or exact; 'seed' is the former name")
    p.add_argument("--roughness", default="constant", choices=("constant", "stretch"),
                   help="stretch: sigma follows the strain of the active zone (docs/physics.md §4)")
    p.add_argument("--dt", type=float, default=None, help="largest RK4 step [s]")
    p.add_argument("--max-steps", type=count(1), default=None,
                   help="refuse a firing needing more RK4 steps (default 1e7; raise it if you "
                        "mean it)")
    p.add_argument("--plot", metavar="FILE.png", type=plot_path, help="write a chart")


def _sim_kw(args: argparse.Namespace) -> dict[str, Any]:
    kw: dict[str, Any] = {"mode": args.mode, "kinematics": args.kinematics}
    if args.dt is not None:
        kw["dt"] = args.dt
    if args.roughness != "constant":
        kw["roughness"] = args.roughness
    if args.max_steps is not None:
        kw["max_steps"] = args.max_steps
    return kw


def _simulate_args(p: argparse.ArgumentParser) -> None:
    _scene_args(p)
    p.add_argument("--trajectory", metavar="FILE.csv|FILE.parquet", default=None,
                   help="write the recorded trajectory, CSV or Parquet by the suffix: t_s, x_m, "
                        "v_m_s (SI; every RK4 step of the stroke, 32 exact points per coast; "
                        "Parquet needs pyarrow, in the studies extra)")


@command("simulate", "one firing of one actuator: travel, outcome, timing", _simulate_args)
def cmd_simulate(args: argparse.Namespace) -> None:
    """One firing of the scene (SI options); travel [m], outcome and timing [s]."""
    from ..studies.sweep import Scene

    scene = Scene(preset=args.preset, freq=args.freq, stroke=args.stroke, x0=args.x0,
                  wavelength=args.wavelength, profile=args.profile, sim_kw=_sim_kw(args))
    sim = scene.simulator()
    scene.run()  # load the compiled kernel first, so wall_time_s is the steady-state figure
    if args.trajectory:
        _trajectory_format(args.trajectory)  # refuse a bad name before simulating
    res = scene.run(record=bool(args.plot or args.trajectory))
    out: dict[str, Any] = {
           "preset": args.preset, "freq_hz": args.freq, "stroke_m": args.stroke, "x0_m": args.x0,
           "profile": args.profile, "mode": args.mode, "kinematics": args.kinematics,
           "dt_s": sim.dt, "steps_per_stroke": sim.steps_per_stroke(args.freq),
           **res.to_dict(), "rest_time_s": res.rest_time_s}
    if args.plot:
        from ..plots import plot_firing

        out["plot"] = str(plot_firing(res, args.freq, args.plot, stroke=args.stroke))
    if args.trajectory:
        fmt = _trajectory_format(args.trajectory)
        out[f"trajectory_{fmt}"] = _write_trajectory(res.trajectory, args.trajectory, fmt)
    emit(args, out)


def _trajectory_format(path: str) -> str:
    """``csv`` or ``parquet`` from the file's suffix; ValueError otherwise or without pyarrow."""
    fmt = path.rsplit(".", 1)[-1].lower() if "." in path else ""
    if fmt not in ("csv", "parquet"):
        raise ValueError(f"--trajectory {path!r}: give a .csv or .parquet file name")
    if fmt == "parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise ValueError("--trajectory FILE.parquet needs pyarrow: pip install "
                             "'microconveyor-env[studies]'") from None
    return fmt


def _write_trajectory(traj: Any, path: str, fmt: str = "csv") -> str:
    """The recorded ``t_s, x_m, v_m_s`` as CSV (full precision) or Parquet (float64 columns),
    SI; written whole or not at all."""
    import os

    import numpy as np

    cols = ("t_s", "x_m", "v_m_s")
    data = {c: np.asarray(traj[c], float) for c in cols}
    tmp = f"{path}.tmp"
    if fmt == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        pq.write_table(pa.table(data), tmp)
    else:
        np.savetxt(tmp, np.column_stack([data[c] for c in cols]), delimiter=",",
                   header=",".join(cols), comments="", fmt="%.17g")
    os.replace(tmp, path)
    return path


def _sweep_args(p: argparse.ArgumentParser) -> None:
    _scene_args(p, sweep=True)
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.add_argument("--max-points", type=count(1, 10 ** 9), default=None,
                   help="refuse sweeps of more points (default 10000; raise it if you mean it)")


@command("sweep", "travel versus one parameter (frequency by default) and the feasible window",
         _sweep_args)
def cmd_sweep(args: argparse.Namespace) -> None:
    """Travel [m] versus one swept parameter (in its SI unit) and the feasible window."""
    from ..studies.sweep import SWEEPABLE, Scene, parse_values, sweep, value_key

    given = {k: getattr(args, k) for k in SWEEPABLE if getattr(args, k, None) is not None}
    swept = [k for k, v in given.items() if k != "profile" and (":" in v or "," in v)]
    if "profile" in given and "," in given["profile"]:
        swept.append("profile")
    if not swept and DEFAULT_SWEEP[0] not in given:  # frequency by default
        given[DEFAULT_SWEEP[0]] = DEFAULT_SWEEP[1]
        swept = [DEFAULT_SWEEP[0]]
    if len(swept) != 1:
        fixed = "" if swept else ", and --freq is fixed, so the frequency is not swept"
        raise ValueError(f"give exactly one swept parameter as start:stop:step or a list "
                         f"(got {swept or 'none'}{fixed}); e.g. --freq 200:1500:25")
    param = swept[0]
    base: dict[str, Any] = {}
    for k, v in given.items():
        if k != param:
            base[k] = v if k == "profile" else parse_values(v, k, 1)[0]
    scene = Scene(preset=args.preset, sim_kw=_sim_kw(args), **base)
    limit = {} if args.max_points is None else {"max_points": args.max_points}
    values = parse_values(given[param], param, **limit)
    res = sweep(scene, param, values, progress=not args.no_progress, **limit)
    out: dict[str, Any] = {"preset": args.preset,
           **{value_key(k): getattr(scene, k) for k in SWEEPABLE if k != param}, **res}
    if args.plot:
        from ..plots import plot_sweep

        out["plot"] = str(plot_sweep(res, args.plot, f"preset {args.preset}: travel of one "
                                                     f"firing versus {param}"))
    emit(args, out, _sweep_text(res))


def _sweep_text(res: dict[str, Any]) -> str:
    from .human import format_value

    lines = [f"{res['param']:>12s}  travel [µm]  outcome"]
    for v, d, o in zip(res[res["values_key"]], res["displacement_m"], res["outcome"], strict=True):
        shown = format_value(res["values_key"], v)[1]  # in the unit people read
        lines.append(f"{shown:>12s}  {d * 1e6:11.2f}  {o}")
    key = "window" + res["values_key"][len(res["param"]):]
    window = res.get(key)
    if window is not None:
        lo, hi = (format_value(res["values_key"], v)[1] for v in window)
        lines.append(f"feasible window: {lo} to {hi}")
    elif res.get("no_window_reason"):  # a window was looked for and there is none: say why
        lines.append(res["no_window_reason"])
    return "\n".join(lines)


def _accuracy_args(p: argparse.ArgumentParser) -> None:
    preset_arg(p)
    p.add_argument("--plot", metavar="FILE.png", type=plot_path, help="write the chart")
    p.add_argument("--repeats", type=count(1, 10_000), default=30,
                   help="timed repeats per setting")
    p.add_argument("--episode", action="store_true",
                   help="whole MicroConveyor-v0 episodes (final position and outcome) instead of "
                        "the single reference firing")
    p.add_argument("--per-category", type=count(1, 10_000), default=60,
                   help="--episode: episodes per category (4 categories)")
    p.add_argument("--seed", type=int, default=0, help="--episode: seed of the episode set")


@command("accuracy", "speed versus accuracy of the integrator settings (chart + default choice)",
         _accuracy_args)
def cmd_accuracy(args: argparse.Namespace) -> None:
    """The speed/accuracy study of one firing (or, ``--episode``, of whole episodes)."""
    if args.episode:
        return _accuracy_episode(args)
    from ..studies.accuracy import accuracy_study

    study = accuracy_study(args.preset, repeats=args.repeats, progress=True)
    if args.plot:
        from ..plots import plot_accuracy

        study["plot"] = str(plot_accuracy(study, args.plot))
    emit(args, study, _accuracy_text(study))


def _accuracy_text(study: dict[str, Any]) -> str:
    """The speed/accuracy table of one firing and the default it picks, in the units people
    read."""
    from .human import format_table, format_value

    def show(key: str, v: Any) -> str:
        return format_value(key, v)[1]

    lines = [f"the firing: {show('freq_hz', study['freq_hz'])}, stroke "
             f"{show('stroke_m', study['stroke_m'])}, start {show('x0_m', study['x0_m'])}; error "
             f"against the reference dt = {show('reference_dt_s', study['reference_dt_s'])}, "
             f"tolerance {show('tolerance_m', study['tolerance_m'])}",
             format_table(study["rows"])]
    d = study["default"]
    lines.append(f"default: {d['mode']} mode, {d['kinematics']} kinematics, dt = "
                 f"{show('dt_s', d['dt_s'])} ({d['steps_per_stroke']} steps per stroke): error "
                 f"{show('error_m', d['error_m'])}, {show('wall_time_s', d['wall_time_s'])} per "
                 "firing" if d else "default: no setting within the tolerance")
    return "\n".join(lines)


def _accuracy_episode(args: argparse.Namespace) -> None:
    from ..studies.episodes import episode_study

    if args.preset not in ("feasibility", "dissertation", "seed"):
        raise ValueError("--episode runs MicroConveyor-v0's own preset (feasibility); drop --preset")
    study = episode_study(n_per_category=args.per_category, seed=args.seed,
                          repeats=min(args.repeats, 5), progress=True)
    if args.plot:
        from ..plots import plot_episode_accuracy

        study["plot"] = str(plot_episode_accuracy(study, args.plot))
    emit(args, study, _episode_text(study))


def _episode_text(study: dict[str, Any]) -> str:
    """The episode accuracy table and the recommended default, in the units people read."""
    from .human import format_value

    def show(key: str, v: Any) -> str:
        return "n/a" if v is None else format_value(key, v)[1]

    counts = ", ".join(f"{n} {c}" for c, n in study["counts"].items())
    lines = [f"{study['episodes']} episodes ({counts}); reference: event mode, dt = "
             f"{show('dt_s', study['reference_dt_s'])} (halving it moves no final position by more "
             f"than {show('error_m', study['reference_half_dt_check']['max_error_m'])})",
             "errors of the final position against the reference (episodes of the same outcome); "
             "outc./succ.: outcome and success disagreements",
             f"{'mode':>8} {'dt':>9} {'min':>4} {'median':>10} {'p95':>10} {'max':>10} "
             f"{'outc.':>5} {'succ.':>5} {'steps':>6} {'per episode':>11}"]
    for r in study["rows"]:
        lines.append(f"{r['mode']:>8} {show('dt_s', r['dt_s']):>9} {r['min_steps']:4d} "
                     f"{show('e_m', r['median_error_m']):>10} {show('e_m', r['p95_error_m']):>10} "
                     f"{show('e_m', r['max_error_m']):>10} "
                     f"{r['outcome_disagreements']:5d} {r['success_disagreements']:5d} "
                     f"{r['rk4_steps_per_episode']:6.0f} "
                     f"{show('t_s', r['wall_per_episode_s']):>11}")
    rec = study["recommended"]
    lines.append("recommended default: " + (f"{rec['mode']} mode, dt = {show('dt_s', rec['dt_s'])}, "
                                            f"min_steps = {rec['min_steps']}" if rec
                                            else "none meets the bar"))
    return "\n".join(lines)


def _bench_args(p: argparse.ArgumentParser) -> None:
    preset_arg(p)
    p.add_argument("--repeats", type=count(1, 1_000_000), default=500,
                   help="timed repeats per mode")
    p.add_argument("--skip-reference", action="store_true",
                   help="do not run the (slow) plain-Python reference")
    p.add_argument("--plane", action="store_true",
                   help="also time one firing in the plane (docs/physics.md §10) against the same "
                        "firing on the line: the 2-D/1-D cost ratio")


@command("bench", "kernel speed on the reference firing, against the dissertation-style loop "
                  "(--plane: and in the plane)", _bench_args)
def cmd_bench(args: argparse.Namespace) -> None:
    """Kernel wall times [s] per mode, against the plain-Python reference loop."""
    from ..studies.bench import bench_modes

    out: dict[str, Any] = {"modes": bench_modes(args.preset, repeats=args.repeats)}
    if args.plane:
        from ..studies.bench import bench_plane

        out["plane"] = bench_plane(args.preset, repeats=args.repeats)
    if args.skip_reference:
        out["reference"] = None
        out["reference_note"] = "skipped"
    else:
        from ..presets import load_preset
        from ..studies.reference_loop import converged_dt

        contact = load_preset(args.preset).contact
        ref = converged_dt(contact)
        out["reference"] = ref
        default = out["modes"]["event"]["median_wall_time_s"]
        out["speedup_vs_reference"] = ref["wall_time_s"] / default
    emit(args, out)
