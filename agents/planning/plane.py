"""Planning on the plane (MicroConveyor2D-v0, -v1): the scene as a planner sees it, a one-step
controller on the plane's firing map, and DAgger's labels from it.

A firing on the plane aims at a point (actions 0-1 times ``pick_reach`` from the part; the
nearest actuator fires), then waits ``delay`` while the part coasts, then strokes. From rest a
radial bump moves the part along the line through the actuator (towards it, or past it), by an
amount that depends only on the radial offset, the frequency and the stroke: the plane's firing
map (:mod:`microconveyor_env.physics.plane.firing_map`) answers that in under a microsecond.

* :class:`PlaneScene`: the candidate firings from a part (every actuator the aim can pick,
  aimed at exactly, times a grid of frequencies and strokes, with a delay long enough that the
  part has come to rest when the stroke starts: :meth:`PlaneScene.delay_s`), each one's
  predicted rest on the map, and the full model's answer for a few of them, fired on the plane's
  own part container (:class:`~microconveyor_env.envs.plane.state.PlaneConveyor`, its compiled
  step, the model part's friction and mass factors written into its constants directly), bit
  for bit what the env does with that action on a part of those factors and no execution noise.
* :class:`PlaneController`: from many parts at once, rank every candidate on the map (a
  candidate next to one the map does not trust, within ``margin`` cells of frequency and stroke,
  is refused: a margin from detachment), fire the best few on the full model, and choose the one
  whose confirmed rest scores best (among those within ``slack_m`` of the best, the gentlest:
  lowest frequency, then smallest stroke); optionally only if a part ``1 + heavier`` times
  heavier does not detach under it. The score is the rest's distance to the target; with
  ``lookahead`` a rest outside the tolerance scores what one more firing could reach from it
  (:meth:`PlaneScene.next_error`): the part is first put on a line through an actuator and the
  target, then pulled along it onto the target, rather than stopped wherever the first landing
  inside the tolerance happens to be (the episode ends there). :meth:`PlaneController.label` is DAgger's labeller
  for a batched plane env; :func:`play` runs the controller on a batched env, one episode per
  target.

The model is nominal (friction and mass factors 1); it never sees an episode's factors or noise.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from microconveyor_env.envs.core.actions import constants as action_constants
from microconveyor_env.envs.core.randomisation import apply_factors
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.envs.plane.firing_map import firing_map
from microconveyor_env.envs.plane.state import PlaneConveyor
from microconveyor_env.envs.plane.vector import MicroConveyor2DVectorEnv
from microconveyor_env.physics import dynamics_kernel as kernel
from microconveyor_env.physics.plane import kernel as plane_kernel

from .rest_expert import MIN_GAIN, RestRanking, check_in, check_integers

AIMS = 9                 # at most 3 x 3 actuators an aim picks from any part
MODEL_FACTORS = (0.5, 2.0)   # the model container's factor bounds (a model part's factors)
CHECKED = 8              # candidates per part checked on the heavier part, in the order chosen
NO_LABEL = np.array([0.0, 0.0, -1.0, -1.0, -1.0], np.float32)   # the weakest firing, no delay


@dataclass(frozen=True)
class PlaneSettings:
    """The controller: ``frequencies`` and ``strokes`` [-] candidates evenly over actions 2 and
    3 in [-1, 1]; ``margin`` [-] cells of that grid from a candidate the map does not trust;
    ``confirm`` [-] per part, this many first in the controller's order and this many nearest
    not among them are fired on the full model; ``slack_m`` [m] how much worse than the best
    score a gentler firing may score (0: the best); ``heavier`` δ [-]: a firing that
    detaches a part 1 + δ times heavier is passed over (0: no check); ``delay_factor`` [-] and
    ``delay_margin_s`` [s]: the delay is the nominal time the part takes to come to rest times
    the factor plus the margin (:meth:`PlaneScene.delay_s`). ``lookahead``: a firing that
    leaves the part outside the tolerance is scored by where the next firing could then put it
    (:meth:`PlaneScene.next_error`), plus ``extra_step_m`` [m] and ``step_error`` [-] times that
    next firing's travel (what noise and unknown factors make of it), except in the last
    ``greedy_last`` [-] firings of the episode and for parts resting farther than
    ``lookahead_within_m`` [m] from their target; off: every firing is scored by its own
    landing's distance to the target."""

    frequencies: int = 41
    strokes: int = 6
    margin: int = 1
    confirm: int = 8
    slack_m: float = 0.0
    heavier: float = 0.1
    delay_factor: float = 1.5
    delay_margin_s: float = 2e-3
    lookahead: bool = True
    lookahead_within_m: float = math.inf
    greedy_last: int = 3
    extra_step_m: float = 3e-6
    step_error: float = 0.05

    def __post_init__(self) -> None:
        check_integers(self, (("frequencies", 2), ("strokes", 2), ("margin", 0), ("confirm", 1),
                              ("greedy_last", 0)))
        check_in(self, (("slack_m", 1e-3), ("heavier", 1.0), ("delay_factor", 10.0),
                        ("delay_margin_s", 1.0), ("extra_step_m", 1e-3), ("step_error", 1.0)))
        if not (isinstance(self.lookahead_within_m, (int, float)) and self.lookahead_within_m > 0):
            raise ValueError(f"lookahead_within_m = {self.lookahead_within_m!r} is invalid: "
                             "must be > 0 m (inf: everywhere)")
        if self.delay_factor < 1.0:
            raise ValueError(f"delay_factor = {self.delay_factor!r} is invalid: must be >= 1 "
                             "(a shorter delay starts the stroke on a moving part)")


@dataclass
class PartStates:
    """The state of M parts on the plane (arrays of M, SI): position ``x``, ``y`` [m], velocity
    ``vx``, ``vy`` [m/s], time ``t`` [s], firings so far ``fired`` [-], target ``tx``, ``ty``
    [m]."""

    x: np.ndarray
    y: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    t: np.ndarray
    fired: np.ndarray
    tx: np.ndarray
    ty: np.ndarray

    @classmethod
    def of(cls, parts: Any, rows: Any = slice(None)) -> PartStates:
        """Copies of a part container's arrays (a batched env's ``conveyor.parts``), ``rows``
        only."""
        return cls(*(np.array(getattr(parts, k)[rows]) for k in
                     ("x", "y", "vx", "vy", "t", "fired", "tx", "ty")))

    def __len__(self) -> int:
        return len(self.x)

    def take(self, idx: Any) -> PartStates:
        return PartStates(*(getattr(self, f.name)[idx] for f in dataclasses.fields(self)))


def dilate(bad: np.ndarray, margin: int) -> np.ndarray:
    """``bad`` ``(..., F, H)`` grown by ``margin`` cells along its last two axes (a square)."""
    out = bad.copy()
    for axis in (-2, -1):
        grown = out.copy()
        n = out.shape[axis]
        for k in range(1, min(margin, n - 1) + 1):
            lo = [slice(None)] * out.ndim
            hi = [slice(None)] * out.ndim
            lo[axis], hi[axis] = slice(0, n - k), slice(k, n)
            grown[tuple(lo)] |= out[tuple(hi)]
            grown[tuple(hi)] |= out[tuple(lo)]
        out = grown
    return out


class PlaneScene:
    """The plane as a planner sees it (module docstring). ``config``: the scene as the real env
    has it (its randomisation is the real part's, never the model's)."""

    def __init__(self, config: PlaneEnvConfig) -> None:
        if not isinstance(config, PlaneEnvConfig):
            raise ValueError(f"PlaneScene serves the plane (MicroConveyor2D-v0, -v1), not "
                             f"{type(config).__name__}")
        self.config = config
        self.model_config = dataclasses.replace(
            config, action_noise=0.0, num_threads=1, friction_factor_range=MODEL_FACTORS,
            mass_factor_range=MODEL_FACTORS)
        self.map = firing_map(config)
        self.positions = np.asarray(config.actuator_positions, float)
        self.AC = action_constants(config)
        self._parts: dict[int, PlaneConveyor] = {}
        self.full_firings = 0    # full-model firings so far (map queries are not firings)
        self.map_queries = 0
        self._reach: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def reach_table(self, settings: PlaneSettings) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """At each radial offset node of the map [m]: the radial displacements to rest [m]
        (negative: towards the actuator) one firing can give, as at most ``K`` disjoint
        intervals ``lo, hi`` ``(nodes, K)`` (unused ones empty: lo = +inf). Along the frequency
        axis the displacement is continuous between nodes the map trusts (with ``margin``
        cells to spare), so each run of such nodes at one stroke gives every value between its
        least and its greatest; the runs' intervals are merged."""
        key = settings.margin
        hit = self._reach.get(key)
        if hit is not None:
            return hit
        r, _, f, h = self.map.grid.nodes()
        R, Fq, Hh = np.meshgrid(r, f, h, indexing="ij")
        d, _, ok = self.map.rest(R.ravel(), Fq.ravel(), Hh.ravel())
        ok = ~dilate(~ok.reshape(R.shape), settings.margin)
        d = d.reshape(R.shape)
        rows: list[list[tuple[float, float]]] = []
        for i in range(len(r)):
            spans = [(0.0, 0.0)]            # the part stays where it rests (a far actuator)
            for k in range(len(h)):
                run: list[float] = []
                for j in range(len(f) + 1):
                    if j < len(f) and ok[i, j, k]:
                        run.append(float(d[i, j, k]))
                    elif run:
                        spans.append((min(run), max(run)))
                        run = []
            spans.sort()
            merged = [list(spans[0])]
            for lo, hi in spans[1:]:
                if lo <= merged[-1][1]:
                    merged[-1][1] = max(merged[-1][1], hi)
                else:
                    merged.append([lo, hi])
            rows.append([(a, b) for a, b in merged])
        K = max(len(x) for x in rows)
        lo_t = np.full((len(r), K), np.inf)
        hi_t = np.full((len(r), K), np.inf)
        for i, row in enumerate(rows):
            for k, (a, b) in enumerate(row):
                lo_t[i, k], hi_t[i, k] = a, b
        self._reach[key] = (r, lo_t, hi_t)
        return self._reach[key]

    def next_error(self, p: np.ndarray, target: np.ndarray, settings: PlaneSettings
                   ) -> tuple[np.ndarray, np.ndarray]:
        """For parts resting at ``p`` ``(..., 2)`` [m]: how near ``target`` (same shape) one
        more firing could bring each, and how far that firing moves it [m]. Each actuator the
        aim can pick from the part, aimed at exactly, moves it along the line through the
        actuator by any radial displacement of :meth:`reach_table` at the nearest offset node;
        the part's own place (no move) counts too."""
        c = self.config
        r_nodes, lo_t, hi_t = self.reach_table(settings)
        step = r_nodes[1] - r_nodes[0]
        ix = np.clip(np.floor(p[..., 0] / c.spacing + 0.5), 0, c.nx - 1).astype(int)
        iy = np.clip(np.floor(p[..., 1] / c.spacing + 0.5), 0, c.ny - 1).astype(int)
        best = np.hypot(*np.moveaxis(target - p, -1, 0))
        travel = np.zeros_like(best)
        gx, gy = target[..., 0] - p[..., 0], target[..., 1] - p[..., 1]
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                jx = np.clip(ix + dx, 0, c.nx - 1)
                jy = np.clip(iy + dy, 0, c.ny - 1)
                ax, ay = jx * c.spacing, jy * c.spacing
                aim_x = np.clip((ax - p[..., 0]) / c.pick_reach, -1.0, 1.0)
                aim_y = np.clip((ay - p[..., 1]) / c.pick_reach, -1.0, 1.0)
                pickable = self.pick(p[..., 0], p[..., 1], aim_x, aim_y) == jx + c.nx * jy
                d = p - np.stack([ax, ay], -1)
                r = np.hypot(d[..., 0], d[..., 1])
                safe = np.where(r > 0.0, r, 1.0)
                ex, ey = d[..., 0] / safe, d[..., 1] / safe
                along = gx * ex + gy * ey
                perp = np.abs(gx * ey - gy * ex)
                node = np.rint(r / step).astype(int)
                inside = pickable & (r > 0.0) & (node < len(r_nodes))
                node = np.minimum(node, len(r_nodes) - 1)
                lo, hi = lo_t[node], hi_t[node]                     # (..., K)
                moved_k = np.clip(along[..., None], lo, hi)
                gap = np.where(np.isfinite(lo), np.abs(along[..., None] - moved_k), np.inf)
                k = np.argmin(gap, axis=-1)
                moved = np.take_along_axis(moved_k, k[..., None], -1)[..., 0]
                e2 = np.where(inside, np.hypot(perp, along - moved), np.inf)
                better = e2 < best
                best = np.where(better, e2, best)
                travel = np.where(better, np.abs(moved), travel)
        return best, travel

    def score(self, landing: np.ndarray, target: np.ndarray, last: np.ndarray,
              settings: PlaneSettings) -> np.ndarray:
        """The controller's score [m] of firings landing at ``landing`` ``(..., 2)`` for parts
        with ``target`` (broadcast): the landing's distance to the target where it is within
        the tolerance (the episode ends there), where the firing is the episode's ``last``
        (broadcast) or without lookahead; else the smaller of that and what one more firing
        could reach (:meth:`next_error`) plus ``extra_step_m`` and ``step_error`` times its
        travel."""
        d = np.hypot(*np.moveaxis(landing - target, -1, 0))
        if not settings.lookahead:
            return d
        fin = np.isfinite(d)
        safe = np.where(fin[..., None], landing, target)
        nxt, travel = self.next_error(safe, np.broadcast_to(target, safe.shape), settings)
        two = nxt + settings.extra_step_m + settings.step_error * travel
        done = (d <= self.config.tolerance) | np.asarray(last)
        return np.where(fin, np.where(done, d, np.minimum(d, two)), np.inf)

    # ------------------------------------------------------------------ the env's rules
    def pick(self, x: np.ndarray, y: np.ndarray, a0: np.ndarray, a1: np.ndarray) -> np.ndarray:
        """The actuator the aim ``(a0, a1)`` picks from a part at ``(x, y)`` [m] (the env's rule,
        :func:`microconveyor_env.envs.plane.task.pick`, on float64 values of the actions)."""
        c = self.config

        def nearest(u: np.ndarray, n: int) -> np.ndarray:
            return np.clip(np.floor(u + 0.5), 0, n - 1).astype(int)

        ax = x + np.clip(a0, -1.0, 1.0) * c.pick_reach
        ay = y + np.clip(a1, -1.0, 1.0) * c.pick_reach
        return nearest(ax / c.spacing, c.nx) + c.nx * nearest(ay / c.spacing, c.ny)

    def decode(self, a2: np.ndarray, a3: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frequency [Hz] and stroke [m] of actions 2 and 3 (the env's decoding of float64
        values)."""
        AC = self.AC
        u2 = (np.clip(a2, -1.0, 1.0) + 1.0) * 0.5
        u3 = (np.clip(a3, -1.0, 1.0) + 1.0) * 0.5
        return AC.f0 * np.exp(u2 * AC.log_span), AC.h0 + u3 * AC.h_span

    def coast(self, s: PartStates) -> tuple[np.ndarray, np.ndarray]:
        """Where each part comes to rest on the still plane on the nominal model ``(M, 2)`` [m]
        and how long that takes [s] (0 for a resting part)."""
        P, (tu, tq, tqu) = self.map.plane.params, self.map.plane.tables
        rest = np.empty((len(s), 2))
        t = np.zeros(len(s))
        for i in range(len(s)):
            x, y, _, _, used, _, _ = plane_kernel.coast(float(s.x[i]), float(s.y[i]),
                                                        float(s.vx[i]), float(s.vy[i]), math.inf,
                                                        P, tu, tq, tqu)
            rest[i] = x, y
            t[i] = used
        return rest, t

    def delay_s(self, coast_s: np.ndarray, settings: PlaneSettings) -> np.ndarray:
        """The delay [s] before a stroke for parts that come to rest ``coast_s`` [s] from now on
        the nominal model: 0 for a resting part, else ``delay_factor`` times that plus
        ``delay_margin_s`` (a part of other friction and mass, or fired with execution noise on
        its delay, still rests before the stroke), within the config's delay range."""
        lo, hi = self.config.delay_range
        d = np.where(coast_s > 0.0, settings.delay_factor * coast_s + settings.delay_margin_s,
                     0.0)
        return np.clip(d, lo, hi)

    def delay_action(self, delay: np.ndarray) -> np.ndarray:
        """Action 4 (float32) that decodes to at least ``delay`` [s]."""
        lo, hi = self.config.delay_range
        if hi == lo:
            return np.zeros(np.shape(delay), np.float32)
        a = np.clip(2.0 * (np.asarray(delay) - lo) / (hi - lo) - 1.0, -1.0, 1.0)
        a32 = a.astype(np.float32)
        short = lo + (a32.astype(float) + 1.0) * 0.5 * (hi - lo) < np.asarray(delay)
        return np.where(short, np.nextafter(a32, np.float32(2.0)), a32).clip(-1, 1).astype(
            np.float32)

    # ------------------------------------------------------------------ candidates
    def candidates(self, s: PartStates, settings: PlaneSettings
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every candidate firing from each part's state: the actions ``(M, AIMS, F, H, 5)``
        float32 (each actuator the aim can pick from where the part is now, aimed at exactly;
        frequencies and strokes evenly over [-1, 1]; the delay of :meth:`delay_s`), which aims
        exist ``(M, AIMS)``, the actuator of each aim ``(M, AIMS)``, where each part rests
        before its stroke ``(M, 2)`` [m] and the delay [s] ``(M,)``."""
        c = self.config
        m, F, H = len(s), settings.frequencies, settings.strokes
        rest, t_coast = self.coast(s)
        delay = self.delay_s(t_coast, settings)
        a4 = self.delay_action(delay)
        ix = np.clip(np.floor(s.x / c.spacing + 0.5), 0, c.nx - 1).astype(int)
        iy = np.clip(np.floor(s.y / c.spacing + 0.5), 0, c.ny - 1).astype(int)
        di = np.array([-1, 0, 1])
        jx = np.clip(ix[:, None, None] + di[None, :, None], 0, c.nx - 1)
        jy = np.clip(iy[:, None, None] + di[None, None, :], 0, c.ny - 1)
        j = (jx + c.nx * jy).reshape(m, AIMS)
        aim = ((self.positions[j] - np.stack([s.x, s.y], 1)[:, None, :]) / c.pick_reach)
        aim = np.clip(aim, -1.0, 1.0).astype(np.float32)
        picked = self.pick(np.repeat(s.x, AIMS), np.repeat(s.y, AIMS),
                           aim[..., 0].ravel().astype(float), aim[..., 1].ravel().astype(float))
        valid = picked.reshape(m, AIMS) == j
        # the same actuator twice (at an edge): keep the first
        for k in range(1, AIMS):
            valid[:, k] &= ~np.any(j[:, :k] == j[:, k:k + 1], axis=1)
        acts = np.empty((m, AIMS, F, H, 5), np.float32)
        acts[..., 0] = aim[..., 0][:, :, None, None]
        acts[..., 1] = aim[..., 1][:, :, None, None]
        acts[..., 2] = np.linspace(-1.0, 1.0, F, dtype=np.float32)[None, None, :, None]
        acts[..., 3] = np.linspace(-1.0, 1.0, H, dtype=np.float32)[None, None, None, :]
        acts[..., 4] = a4[:, None, None, None]
        return acts, valid, j, rest, delay

    def predict(self, s: PartStates, settings: PlaneSettings
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every candidate (:meth:`candidates`) on the firing map: the actions ``(M, AIMS, F,
        H, 5)``, the predicted rests ``(M, AIMS, F, H, 2)`` [m], whether each is allowed (the
        aim exists, the map trusts it and every candidate within ``margin`` cells of it, and it
        rests before the episode's time limit) and the rests before the strokes ``(M, 2)``."""
        acts, valid, j, rest, delay = self.candidates(s, settings)
        m, F, H = len(s), settings.frequencies, settings.strokes
        f, h = self.decode(acts[0, 0, :, 0, 2].astype(float), acts[0, 0, 0, :, 3].astype(float))
        n = m * AIMS * F * H
        part = np.broadcast_to(rest[:, None, None, None, :], (m, AIMS, F, H, 2)).reshape(n, 2)
        act = np.broadcast_to(self.positions[j][:, :, None, None, :],
                              (m, AIMS, F, H, 2)).reshape(n, 2)
        ff = np.broadcast_to(f[None, None, :, None], (m, AIMS, F, H)).ravel()
        hh = np.broadcast_to(h[None, None, None, :], (m, AIMS, F, H)).ravel()
        xr, tr, ok = self.map.rest_at(part, act, ff, hh)
        self.map_queries += n
        shape = (m, AIMS, F, H)
        late = (s.t + delay)[:, None, None, None] + np.nan_to_num(tr, nan=np.inf).reshape(shape) \
            > self.config.max_time
        bad = (~ok).reshape(shape) | late
        allowed = ~dilate(bad, settings.margin) & valid[:, :, None, None]
        return acts, xr.reshape(*shape, 2), allowed, rest

    # ------------------------------------------------------------------ the full model
    def _container(self, n: int) -> PlaneConveyor:
        cap = 1 << max(n - 1, 0).bit_length()   # containers by powers of two, the rest idle
        c = self._parts.get(cap)
        if c is None:
            c = self._parts[cap] = PlaneConveyor(self.model_config, cap, num_threads=1)
        return c

    def fire(self, s: PartStates, actions: np.ndarray, friction_factor: Any = 1.0,
             mass_factor: Any = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One firing of ``actions`` ``(B, 5)`` on the full model from the parts ``s`` (B
        states; their delay coasts them as the env's does), each a model part with
        ``friction_factor`` and ``mass_factor`` [-] (scalars or arrays of B), followed to rest:
        where each comes to rest ``(B, 2)`` [m], when [s] and the outcome code
        (``dynamics_kernel.REST``, ``DETACHED``, ...). The env's own compiled step on a part
        container whose arrays are written directly: bit for bit what the env fires from that
        state with no execution noise, with the part's rest where the env's next delay (or its
        last firing) brings it."""
        b = len(actions)
        c = self._container(b)
        n = len(c.parts.x)
        p = c.parts
        for name in ("x", "y", "vx", "vy", "t", "tx", "ty"):
            arr = getattr(p, name)
            arr[:b] = getattr(s, name)
            arr[b:] = 0.0
        # the model's firing is its episode's last: the part is followed to rest
        p.fired[:] = self.model_config.max_firings - 1
        ff = np.broadcast_to(np.asarray(friction_factor, float), (b,))
        mf = np.broadcast_to(np.asarray(mass_factor, float), (b,))
        base = c.sim.params
        P = c.consts.P
        for i in range(b):
            apply_factors(base, P[i], float(ff[i]), float(mf[i]))
        c.friction_factor[:b], c.mass_factor[:b] = ff, mf
        a = np.zeros((n, 5))
        a[:b] = np.asarray(actions, np.float32)
        active = np.zeros(n, bool)
        active[:b] = True
        out = c.step(a, active)
        self.full_firings += b
        return (np.stack([p.x[:b], p.y[:b]], 1), p.t[:b].copy(), out.outcome[:b].copy())


class PlaneController:
    """The one-step controller on the plane (module docstring): ``choose`` many parts' firings
    at once; ``label`` DAgger's labels for a batched env; ``act`` a batched env's actions."""

    def __init__(self, config: PlaneEnvConfig, settings: PlaneSettings | None = None,
                 scene: PlaneScene | None = None) -> None:
        self.scene = scene if scene is not None else PlaneScene(config)
        self.settings = settings or PlaneSettings()
        s = self.settings
        # the rest scenes' rule (gentleness: the lowest frequency, then the smallest stroke,
        # then the aim)
        self.ranking = RestRanking(AIMS, s.frequencies, s.strokes, s.slack_m, s.confirm)

    def choose(self, s: PartStates) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For each part of ``s``: the firing (actions ``(M, 5)`` float32), whether it brings
        the part closer to its target than where it rests now (on the full model; False: the
        nearest found does not) and where the full nominal model puts the part after it
        ``(M, 2)`` [m] (NaN where no candidate rests)."""
        st, sc = self.settings, self.scene
        m = len(s)
        if m == 0:
            return np.zeros((0, 5), np.float32), np.zeros(0, bool), np.zeros((0, 2))
        rows = np.arange(m)
        acts, xr, allowed, rest = sc.predict(s, st)
        per = acts[0].size // 5
        acts = acts.reshape(m, per, 5)
        target = np.stack([s.tx, s.ty], 1)
        last = s.fired >= self.scene.config.max_firings - max(st.greedy_last, 1)
        if math.isfinite(st.lookahead_within_m):
            rest0, _ = sc.coast(s)
            last = last | (np.hypot(*(rest0 - target).T) > st.lookahead_within_m)
        last = last[:, None]
        err = np.where(allowed.reshape(m, per),
                       sc.score(xr.reshape(m, per, 2), target[:, None, :], last, st), np.inf)
        pick = self.ranking.shortlist(err)
        mapped = np.isfinite(np.take_along_axis(err, pick, axis=1))
        sel = acts[rows[:, None], pick]                                    # (m, c, 5)
        c = pick.shape[1]
        rep = s.take(np.repeat(rows, c))
        xf, _, code = sc.fire(rep, sel.reshape(-1, 5))
        xf = xf.reshape(m, c, 2)
        rests = mapped & (code.reshape(m, c) == kernel.REST)
        full = np.where(rests, sc.score(xf, target[:, None, :], last, st), np.inf)
        order = self.ranking.ordered(full, self.ranking.rank[pick])
        best = order[:, 0]
        if st.heavier > 0.0:   # the first in that order that a heavier part survives
            def survives(top: np.ndarray) -> np.ndarray:
                kk = top.shape[1]
                cand = np.isfinite(np.take_along_axis(full, top, axis=1))
                idx = np.flatnonzero(cand.ravel())
                out = np.zeros(m * kk, bool)
                if idx.size:   # only those that rest on the nominal model are fired again
                    _, _, hcode = sc.fire(s.take(np.repeat(rows, kk)[idx]),
                                          sel[rows[:, None], top].reshape(-1, 5)[idx],
                                          mass_factor=1.0 + st.heavier)
                    out[idx] = hcode == kernel.REST
                return out.reshape(m, kk)
            best = self.ranking.first_surviving(order, full, CHECKED, survives)
        now = sc.score(rest, target, np.zeros(m, bool), st)
        ok = full[rows, best] < now - MIN_GAIN
        landing = np.where(np.isfinite(full[rows, best])[:, None], xf[rows, best], np.nan)
        chosen = sel[rows, best]
        stuck = np.flatnonzero(~ok)
        if st.lookahead and stuck.size:
            # what the lookahead promised is not to be had: the nearest landing instead
            greedy = PlaneController(self.scene.config, dataclasses.replace(st, lookahead=False),
                                     scene=sc)
            chosen[stuck], ok[stuck], landing[stuck] = greedy.choose(s.take(stuck))
        return chosen, ok, landing

    def act(self, venv: Any, rows: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`choose` for the parts of the batched plane env ``venv`` (``rows``: bool
        ``(N,)``, those only; the others get :data:`NO_LABEL`): actions ``(N, 5)`` float32,
        whether each brings its part closer, the full model's landing ``(N, 2)`` [m]."""
        parts = venv.conveyor.parts
        n = len(parts.x)
        live = np.ones(n, bool) if rows is None else np.asarray(rows, bool)
        acts = np.tile(NO_LABEL, (n, 1))
        ok = np.zeros(n, bool)
        landing = np.full((n, 2), np.nan)
        idx = np.flatnonzero(live)
        if idx.size:
            acts[idx], ok[idx], landing[idx] = self.choose(PartStates.of(parts, idx))
        return acts, ok, landing

    def label(self, obs: np.ndarray, venv: Any,
              live: np.ndarray) -> tuple[np.ndarray, np.ndarray, None]:
        """DAgger's labels for the parts of the batched plane env ``venv`` (observed as
        ``obs``), its rows ``live`` only: the actions ``(M, 5)`` float32, which have one (the
        firing brings the part closer on the full nominal model) and no re-aim flags."""
        acts, ok, _ = self.act(venv, live)
        return acts, ok & np.asarray(live, bool), None


# DAgger's labels: the nearest landing without lookahead (what a network imitates best: the
# lookahead's staging firings depend on the target's geometry in ways a small network does not
# learn in minutes), the gentlest within 20 µm of it, 3 cells from detachment on a 21 x 4 grid
LABEL_SETTINGS = PlaneSettings(frequencies=21, strokes=4, margin=3, slack_m=20e-6,
                               lookahead=False)


def labeller(config: PlaneEnvConfig, settings: PlaneSettings = LABEL_SETTINGS
             ) -> PlaneController:
    """DAgger's expert for a plane scene: ``labeller(config).label(obs, venv, live)`` gives the
    labels of a batched env's parts (:meth:`PlaneController.label`)."""
    return PlaneController(config, settings)


@dataclass
class PlayResult:
    """Episodes of :func:`play` (arrays over the targets, SI): ``distance_m`` from the target at
    the end [m], ``outcome``, ``success`` (at rest within tolerance), ``firings`` [-], ``moving``
    [-] strokes that started on a part still moving (its own friction and mass, the delay as
    fired), ``wall_s`` the controller's and the env's time for all [s]."""

    distance_m: np.ndarray
    outcome: np.ndarray
    success: np.ndarray
    firings: np.ndarray
    moving: np.ndarray
    wall_s: float

    def summary(self) -> dict[str, float]:
        n = len(self.distance_m)
        return {"targets": n, "success_rate": float(self.success.mean()),
                "median_error_m": float(np.median(self.distance_m)),
                "p90_error_m": float(np.percentile(self.distance_m, 90)),
                "detach_rate": float(np.mean(self.outcome == "detached")),
                "mean_firings": float(self.firings.mean()),
                "moving_strokes": int(self.moving.sum()),
                "wall_ms_per_target": 1e3 * self.wall_s / max(n, 1)}


def play(controller: PlaneController, config: PlaneEnvConfig, targets: np.ndarray,
         seed: int = 0) -> PlayResult:
    """One episode per target ``(n, 2)`` [m] on the batched env of ``config`` (sub-env ``i``
    seeded ``seed + i``: its randomisation draws), each firing chosen by ``controller``."""
    targets = np.asarray(targets, float).reshape(-1, 2)
    n = len(targets)
    env = MicroConveyor2DVectorEnv(n, config=dataclasses.replace(config, num_threads=1))
    t0 = time.perf_counter()
    env.reset(seed=seed, options={"target": targets})
    c = env.conveyor
    done = np.zeros(n, bool)
    dist = np.full(n, np.nan)
    outcome = np.full(n, "", dtype=object)
    success = np.zeros(n, bool)
    firings = np.zeros(n, int)
    moving = np.zeros(n, int)
    tu, tq, tqu = c.consts.tu, c.consts.tq, c.consts.tqu
    while not done.all():
        live = ~done
        acts, _, _ = controller.act(env, live)
        stop = np.zeros(n)   # when each live part would come to rest, its own factors [s]
        for i in np.flatnonzero(live):
            p = c.parts
            stop[i] = plane_kernel.coast(p.x[i], p.y[i], p.vx[i], p.vy[i], math.inf,
                                         c.consts.P[i], tu, tq, tqu)[4]
        _, _, term, trunc, info = env.step(acts)
        moving[live] += info["delay_s"][live] < stop[live]
        firings[live] += 1
        end = live & (term | trunc)
        dist[end] = info["distance_m"][end]
        outcome[end] = info["outcome"][end]
        success[end] = info["is_success"][end]
        done |= end
    env.close()
    return PlayResult(dist, outcome, success, firings, moving, time.perf_counter() - t0)
