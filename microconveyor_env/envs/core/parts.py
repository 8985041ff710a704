"""The container of N parts that every scene's envs own: the compiled step bound once, the
serial or parallel loop chosen by measuring, the active mask, the reset options checked whole
(targets, saved part states: :mod:`.part_state`), pickling.

A scene subclasses :class:`PartsBase` with its state arrays (typed NamedTuples, as brax's typed
``State``) and says which compiled functions step and observe them (:meth:`PartsBase.compiled`);
the single env owns one with N = 1, the batched env one with N = ``num_envs``, so both run the
same code and give bit-identical rollouts.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple, TypeVar

import numba
import numpy as np

from ...physics.contact_table import TableRangeError
from ...physics.materials import ParameterError
from ...physics.simulator import Simulator
from . import randomisation
from .checks import check_actions, check_reset_options
from .part_state import SavedState, check_saved_in, reset_state
from .threads import ThreadChooser, threads

T = TypeVar("T")


class BoundCall:
    """A compiled function bound to arguments whose numba types never change (arrays that are
    only ever written in place, immutable NamedTuples).

    The first call goes through numba's dispatcher (which compiles or loads the cache and picks
    the overload from the arguments' types); later calls go straight to that overload's native
    entry point. numba's dispatcher has no fast path for NamedTuples: resolving the types of the
    step's ~40 fields costs ~15 us per call (measured: 18 us against 3 us for the whole call of
    a single part that only observes), half of a typical single-env step. Where the entry point
    cannot be had (JIT disabled, or numba picked an overload for converted types), every call
    goes through the dispatcher.
    """

    __slots__ = ("fn", "args", "entry")

    def __init__(self, fn: Callable[..., Any], args: tuple[Any, ...]) -> None:
        self.fn = fn
        self.args = args
        self.entry: Callable[..., Any] | None = None

    def __call__(self) -> Any:
        entry = self.entry
        if entry is not None:
            return entry(*self.args)
        result = self.fn(*self.args)
        try:
            sig = tuple(numba.typeof(a) for a in self.args)
            self.entry = self.fn.get_overload(sig)  # type: ignore[attr-defined]
        except (AttributeError, KeyError, TypeError, ValueError):
            self.entry = self.fn
        return result


def raise_if_beyond_table(outcome: str, sim: Simulator) -> None:
    """TableRangeError when a firing's ``outcome`` says the load left ``sim``'s contact table."""
    if outcome == "load_beyond_table":
        raise TableRangeError(f"the normal load left the contact table ({sim.table.max_load:.3g} "
                              "N) during a stroke; rebuild the table with a larger load_ratio")


def check_table_reach(sim: Any, cfg: Any) -> None:
    """Refuse ``cfg``'s action ranges when its strongest stroke (the top of ``freq_range`` and
    ``stroke_range``) would load the part, the heaviest ``mass_factor_range`` allows too, beyond
    ``sim``'s contact table: checked once when a scene builds its simulator, so steps never need
    to. A ParameterError names ``<config class>.<field>``."""
    owner = type(cfg).__name__
    f, h = np.array([cfg.freq_range[1]]), np.array([cfg.stroke_range[1]])
    try:
        sim.check_firings(f, h)
    except TableRangeError as exc:
        raise ParameterError(f"{owner}.freq_range / stroke_range: {exc}") from None
    heaviest = cfg.mass_factor_range[1]
    if heaviest > 1.0:
        try:
            sim.check_firings(f, h, mass_factor=heaviest)
        except TableRangeError as exc:
            raise ParameterError(f"{owner}.mass_factor_range = {cfg.mass_factor_range!r} is "
                                 f"invalid with these freq_range / stroke_range: a part "
                                 f"{heaviest:g} times heavier: {exc}; lower the upper factor"
                                 ) from None


class Resets(NamedTuple):
    """Checked reset options, one entry per part (None: nothing given, the part draws)."""

    targets: list[Any] | None
    states: list[Any] | None

    def of(self, i: int) -> tuple[Any, Any]:
        """Part ``i``'s (target, state), the arguments of ``reset_part`` after its generator."""
        return (None if self.targets is None else self.targets[i],
                None if self.states is None else self.states[i])


def for_part(i: int, check: Callable[..., T], *args: Any) -> T:
    """``check(*args)`` for part ``i`` of a batch, its error naming the part."""
    try:
        return check(*args)
    except ValueError as exc:
        raise ValueError(f"env {i}: {exc}") from None


class PartsBase:
    """``n`` parts of one scene: the base of every scene's part container.

    A subclass builds its arrays (``parts``, ``consts``, ``action``, ``task``, ``out``) and
    then calls :meth:`_start`; :attr:`components` names the action's components;
    :meth:`compiled` names its
    compiled step (serial, parallel: ``fn(actions, active, parts, consts, action, task, out)``,
    returning how many parts left the contact table) and observation (``fn(*observe_args)``).
    The compiled calls hold these very arrays: write them in place, never rebind them.
    ``num_threads``: as :class:`.threads.ThreadChooser` (the single env passes 1: always the
    serial loop). Pickles (the compiled calls are rebuilt after loading).

    Resets: :meth:`check_reset` checks the options of every part before any changes, through
    the scene's :meth:`check_targets` and :meth:`check_state`; :meth:`reset_part` (the scene's)
    starts one part's episode; :meth:`get_state` saves one part's state. Info: :meth:`errors`
    and :attr:`step_info` (the single and the batched env build their info dicts from them).
    """

    n: int
    config: Any
    # the action's components (named in the messages of refused actions)
    components: tuple[str, ...] = ("frequency", "stroke", "delay")
    # the per-firing info keys: (key, the output array's field, the value a sub-env reset in the
    # same step reports), in the order the info dicts hold them
    step_info: tuple[tuple[str, str, float], ...] = ()
    obs: np.ndarray       # (n, obs_dim) float32: the observations the envs return
    obs_dim: int
    obs_bound: float      # observations lie in [-obs_bound, obs_bound]
    sim: Any
    parts: Any
    consts: Any
    action: Any
    task: Any
    out: Any

    def _start_randomisation(self, config: Any, n: int) -> None:
        """The per-episode randomisation every scene keeps beside its parts
        (:mod:`.randomisation`): whether it is on, each part's factors this episode (1 while it
        is off), and each part's streams with the generator they were derived from."""
        self.randomised: bool = config.randomised
        self.friction_factor: np.ndarray = np.ones(n)  # this episode's factor on the friction
        self.mass_factor: np.ndarray = np.ones(n)      # this episode's factor on the mass
        self._streams: list[Any] = [None] * n
        self._stream_src: list[np.random.Generator | None] = [None] * n

    def _draw_randomisation(self, i: int, rng: np.random.Generator) -> None:
        """With randomisation on, part ``i``'s factors and noise for its next episode, from the
        streams derived from ``rng`` (derived anew when the part's generator is replaced)."""
        if not self.randomised:
            return
        streams = self._streams[i]
        if streams is None or self._stream_src[i] is not rng:  # seeded anew: new streams
            streams = self._streams[i] = randomisation.streams(rng)
            self._stream_src[i] = rng
        noise = self.consts.noise
        self.friction_factor[i], self.mass_factor[i] = randomisation.draw(
            self.config, streams, self.sim.params, self.consts.P[i],
            noise[i] if noise.size else None)

    def _draw_randomisation_many(self, rows: np.ndarray,
                                 rngs: Sequence[np.random.Generator]) -> None:
        """:meth:`_draw_randomisation` for the parts ``rows`` (an index array) at once, part
        ``rows[k]`` from ``rngs[k]``: the same draws, the per-part work only what each part's
        own streams must do."""
        if not self.randomised or not len(rows):
            return
        streams, src = self._streams, self._stream_src
        mine = []
        for i, rng in zip(rows.tolist(), rngs, strict=True):
            s = streams[i]
            if s is None or src[i] is not rng:  # seeded anew: new streams
                s = streams[i] = randomisation.streams(rng)
                src[i] = rng
            mine.append(s)
        noise = self.consts.noise
        self.friction_factor[rows], self.mass_factor[rows] = randomisation.draw_many(
            self.config, mine, self.sim.params, self.consts.P, rows, noise if noise.size else None)

    def _restore_randomisation(self, i: int, state: Any) -> None:
        """Part ``i``'s factors and noise from a checked saved ``state`` (its fields left None
        keep this episode's draws)."""
        if state.friction_factor is not None or state.mass_factor is not None:
            ff = self.friction_factor[i] if state.friction_factor is None else state.friction_factor
            mf = self.mass_factor[i] if state.mass_factor is None else state.mass_factor
            self.friction_factor[i], self.mass_factor[i] = ff, mf
            randomisation.apply_factors(self.sim.params, self.consts.P[i], ff, mf)
        if state.noise is not None:
            self.consts.noise[i] = np.asarray(state.noise)

    def _saved_randomisation(self, i: int) -> tuple[float | None, float | None, Any]:
        """Part ``i``'s (friction factor, mass factor, noise) for its saved state (None while
        randomisation is off; noise None without execution noise)."""
        if not self.randomised:
            return None, None, None
        noise = (tuple(map(tuple, self.consts.noise[i].tolist())) if self.consts.noise.size
                 else None)
        return float(self.friction_factor[i]), float(self.mass_factor[i]), noise

    def _start(self, n: int, num_threads: int | None) -> None:
        """The common tail of a subclass's ``__init__``: the thread chooser, the actions'
        input buffer (envs check their actions straight into it), the active mask, the calls."""
        self.threads = ThreadChooser(num_threads, n)
        self.action_input: np.ndarray = np.zeros((n, len(self.components)))
        self._active = np.ones(n, dtype=np.bool_)
        self._all_active = True
        self._bind()

    def compiled(self) -> tuple[Callable[..., Any], Callable[..., Any], Callable[..., Any],
                                tuple[Any, ...]]:
        """The scene's compiled step (serial, parallel), its observation and that one's
        arguments."""
        raise NotImplementedError

    def observe(self) -> np.ndarray:
        """Every part's observation, into (and returned as) ``obs``: copy to keep it."""
        self._observe()
        return self.obs

    def clear_targets(self) -> None:
        """No target before the first reset (NaN): the single env's part."""
        self.parts.target[:] = np.nan

    def errors(self) -> dict[str, np.ndarray]:
        """The info rows that say how far each part is from its target (first
        ``position_error_m``): arrays of ``n`` rows, the single env's info takes row 0."""
        raise NotImplementedError

    def errors_of(self, i: int) -> dict[str, Any]:
        """Part ``i``'s row of :meth:`errors` as Python numbers (a float, or a tuple of them):
        the single env's info. A scene may give it without building every part's arrays."""
        return {key: val[i].item() if val.ndim == 1 else tuple(val[i].tolist())
                for key, val in self.errors().items()}

    def check_actions(self, actions: Any, n: int | None) -> np.ndarray:
        """The actions checked straight into the input buffer (:func:`.checks.check_actions`:
        ``n`` None the single env's one action, else ``n`` of them)."""
        return check_actions(actions, n, self.action_input, self.components)

    def check_targets(self, given: Any, batched: bool) -> list[Any]:
        """Every part's target from reset's ``"target"`` option, checked: ``batched``, one for
        every part or one per part; else the single env's one."""
        raise NotImplementedError

    def check_state(self, state: Any) -> SavedState:
        """A saved part state (the scene's state class or its dict), checked against the
        config; a one-line ValueError names what is wrong."""
        raise NotImplementedError

    def get_state(self, i: int, env_id: str | None = None) -> SavedState:
        """Part ``i``'s state now, naming ``env_id`` and the config's scene."""
        raise NotImplementedError

    def reset_part(self, i: int, rng: np.random.Generator, target: Any = None,
                   state: Any = None) -> None:
        """Start part ``i``'s next episode, drawing from ``rng``: ``target`` and ``state`` (the
        scene's, as :meth:`check_reset` gives them; None: drawn) override the draws."""
        raise NotImplementedError

    def reset_parts(self, rows: np.ndarray, rngs: Sequence[np.random.Generator]) -> None:
        """Start the next episode of the parts ``rows`` (an index array, ascending), part
        ``rows[k]`` drawing from ``rngs[k]``, without reset options: the batched env's
        autoreset. The same state and draws as :meth:`reset_part` part by part; a scene may
        do it with whole-array writes."""
        for i, rng in zip(rows.tolist(), rngs, strict=True):
            self.reset_part(i, rng)

    def check_reset(self, options: dict[str, Any] | None, batched: bool,
                    env_id: str | None = None) -> Resets:
        """Every part's reset from reset ``options``, all checked before any part changes (a
        refused reset leaves every part as it was): only the keys ``"target"``
        (:meth:`check_targets`) and ``"state"`` (a saved part state: :meth:`check_state`, and
        saved in ``env_id``, the id the env was made with: :func:`.part_state.check_saved_in`),
        not both. ``batched``: a state may also be one per part (a sequence of ``n``);
        otherwise the one given is every part's."""
        options = check_reset_options(options)
        state = reset_state(options)
        n = self.n

        def checked(s: Any) -> SavedState:
            saved = self.check_state(s)
            check_saved_in(saved, env_id)
            return saved

        if state is not None:
            if batched and isinstance(state, (list, tuple)):
                if len(state) != n:
                    raise ValueError(f"{len(state)} part states for {n} envs")
                return Resets(None, [for_part(i, checked, s) for i, s in enumerate(state)])
            return Resets(None, [checked(state)] * n)
        if "target" in options:
            return Resets(self.check_targets(options["target"], batched), None)
        return Resets(None, None)

    def table_simulator(self) -> Simulator:
        """The simulator whose contact table a step's load is checked against."""
        return self.sim

    def _bind(self) -> None:
        """The compiled calls, their arguments built once."""
        serial, parallel, observe, observe_args = self.compiled()
        args = (self.action_input, self._active, self.parts, self.consts, self.action, self.task,
                self.out)
        self._serial = BoundCall(serial, args)
        self._parallel = BoundCall(parallel, args)
        self._observe = BoundCall(observe, observe_args)

    def step(self, a: np.ndarray, active: np.ndarray | None = None) -> Any:
        """Fire once for each part (``active``: those parts only; default all) with the
        checked actions ``a`` (N, action components); returns ``out``. Raises
        ``TableRangeError`` if a stroke loaded a part beyond the contact table."""
        if a is not self.action_input:
            self.action_input[:] = a
        if active is not None:
            self._active[:] = active
            self._all_active = False
        elif not self._all_active:
            self._active.fill(True)
            self._all_active = True
        chooser = self.threads
        if chooser.fixed is not None:  # nothing to choose or measure
            beyond = self._run(chooser.fixed)
        else:
            k = chooser.choose()
            t0 = time.perf_counter()
            beyond = self._run(k)
            chooser.record(k, time.perf_counter() - t0, int(self._active.sum()))
        if beyond:
            raise_if_beyond_table("load_beyond_table", self.table_simulator())
        if self.after_step is not None:
            self.after_step()
        return self.out

    # what a scene does after each step (the line: its observation history), or None
    after_step: Callable[[], None] | None = None

    def _run(self, k: int) -> int:
        """Step with ``k`` threads; the number of parts that left the contact table."""
        if k == 1:
            return int(self._serial())
        with threads(k):
            return int(self._parallel())

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        for name in ("_serial", "_parallel", "_observe"):  # native entry points do not pickle
            del state[name]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._bind()
