"""A Gymnasium environment: drive the robot, a filter localises it (the ``gym`` extra).

``BeaconEnv(scenario="default", filters=("ekf",))``: each step applies the action
``[v, omega]`` [m/s, rad/s] (clipped to the scenario's keyboard limits) for
``ticks_per_step`` simulation ticks while the filters run, exactly as in a headless run.
The reward is pluggable (``reward=``, a callable ``(env, steps) -> float``); the shipped
one, :func:`neg_log_det`, is active localisation: the negative log-determinant of a chosen
filter's covariance after the step (larger when the filter is surer). docs/gym.md documents
the observation, the reward and the episode's end.

pygame is imported only when a frame is drawn (``render_mode="rgb_array"`` or ``"human"``),
by the window's own renderer.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.optional import install_hint

try:
    import gymnasium
    from gymnasium import spaces
    from gymnasium.error import ResetNeeded
except ImportError as exc:  # one line that says what to install
    raise ImportError(install_hint("gymnasium", "beacon_sim.gym (the Gymnasium environment)")) from exc

from beacon_sim.core.arguments import check_seed
from beacon_sim.core.scenario import MAX_TICKS, Scenario, load_scenario
from beacon_sim.core.sensor_kinds import is_scan
from beacon_sim.core.types import Control, Step
from beacon_sim.errors import ArgumentTypeError, UsageError, short_repr
from beacon_sim.runs.live import Session

#: Numbers per observation slot: a beacon sensor's slot is one beacon, a fix sensor's slot
#: is its fix, a range finder's block is :data:`SCAN_FRESH` then one range per beam.
BEACON_SLOT = ("seen", "range_m", "cos_bearing", "sin_bearing")
FIX_SLOT = ("fresh", "x_m", "y_m", "cos_theta", "sin_theta")
SCAN_FRESH = "fresh"
#: A distance sensor's slot per beacon: ``range`` its range, ``tdoa`` its difference against
#: the reference (the reference's slot: heard, 0, is_reference 1).
DISTANCE_SLOT = ("heard", "distance_m", "is_reference")
DISTANCE_KINDS = ("range", "tdoa")
SCAN_RANGE = "scan_range_m"
ENV_ID = "beacon_sim/Localize-v0"
#: What ``gymnasium.make`` takes in a fresh process: Gymnasium 1.x loads no plug-ins, so the
#: module that registers the ID is named before the colon and imported by ``make``.
MAKE_ID = f"beacon_sim.gym:{ENV_ID}"

Reward = Callable[["BeaconEnv", list[Step]], float]


class NegLogDet:
    """Active localisation: ``-log det P`` of ``filter_name``'s covariance after the step
    (P is 3 x 3 over x [m], y [m], theta [rad]; the first filter when None). Shrinking the
    uncertainty ellipsoid's volume by a factor e earns one unit. A class, not a closure, so
    an env holding it pickles."""

    def __init__(self, filter_name: str | None = None):
        self.filter_name = filter_name
        self.__name__ = f"neg_log_det({filter_name or ''})"

    def __repr__(self) -> str:
        return self.__name__

    def __eq__(self, other: object) -> bool:
        return isinstance(other, NegLogDet) and other.filter_name == self.filter_name

    def __hash__(self) -> int:
        return hash((NegLogDet, self.filter_name))

    def __call__(self, env: BeaconEnv, steps: list[Step]) -> float:
        _, cov = env.estimate(self.filter_name or env.filter_names[0])
        if not np.all(np.isfinite(cov)):
            return -float(env.failed_penalty)
        sign, logdet = np.linalg.slogdet(cov)
        return -float(logdet) if sign > 0 else -float(env.failed_penalty)


def neg_log_det(filter_name: str | None = None) -> Reward:
    """The shipped reward, :class:`NegLogDet` of ``filter_name`` (the first filter when None)."""
    return NegLogDet(filter_name)


def check_action(action: Any) -> np.ndarray:
    """``action`` as a float64 ``[v, omega]``: exactly two finite numbers, else a one-line
    :class:`~beacon_sim.errors.UsageError` (a ValueError) saying what was expected."""
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise UsageError(f"action {short_repr(action)}: expected two numbers [v m/s, omega rad/s]") from None
    if a.shape != (2,):
        raise UsageError(f"action of shape {a.shape}: expected shape (2,), [v m/s, omega rad/s]")
    if not np.all(np.isfinite(a)):
        raise UsageError(f"action {a.tolist()}: expected finite numbers [v m/s, omega rad/s] (NaN or inf)")
    return a


#: Most simulation ticks one ``step()`` runs.
MAX_TICKS_PER_STEP = 10_000


class ResetNeededError(UsageError, ResetNeeded):
    """``step()`` (or ``render()``) before ``reset()``: the project's error (a ValueError) that
    is also Gymnasium's ``ResetNeeded``."""


def _whole(label: str, value: Any, hi: int) -> int | None:
    """None, or a whole number from 1 to ``hi`` (not a bool, not a float), else UsageError."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ArgumentTypeError(f"{label}{short_repr(value)}: expected a whole number from 1 to {hi:,}")
    if not 1 <= int(value) <= hi:
        raise UsageError(f"{label}{short_repr(value)}: expected a whole number from 1 to {hi:,}")
    return int(value)


class _Session(Session):
    """A session driven by the agent's action instead of the keyboard or the autopilot."""

    action = Control()

    def next_control(self) -> Control:
        return self.action

    @property
    def drive_mode(self) -> str:
        return "agent"


class BeaconEnv(gymnasium.Env):
    """Localisation with beacons as a Gymnasium environment.

    Parameters
    ----------
    scenario : Scenario, str or Path
        A scenario, or a shipped name / ``.toml`` path.
    filters : sequence of str
        Filter specs run on every tick (``"ekf"``, ``"pf"``, ``"file.py:Class"``).
    reward : callable ``(env, steps) -> float``, optional
        ``steps``: the simulation steps of this env step. Default :func:`neg_log_det` of the
        first filter.
    tracked : str, optional
        The filter whose switching off ends the episode (default the first).
    ticks_per_step : int, optional
        Simulation ticks per env step (default: the fastest sensor's period in ticks, so
        each step can hold a reading of every sensor).
    max_steps : int, optional
        Truncate after this many steps (default: the scenario's duration).
    params : dict, optional
        ``{filter name: {key: value}}`` as ``--set``.
    render_mode : ``"rgb_array"``, ``"human"`` or None
    size : (width, height) of a rendered frame [px].
    failed_penalty : float
        The reward of a step whose tracked filter has no usable covariance.
    """

    #: Gymnasium's metadata; an instance's ``render_fps`` is one step per ``ticks_per_step * dt``.
    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 20}  # noqa: RUF012
    #: [v, omega] [m/s, rad/s] and the encoded readings (docs/gym.md): both boxes.
    action_space: spaces.Box
    observation_space: spaces.Box

    def __init__(self, scenario: Scenario | str | Path = "default", filters: Sequence[str] = ("ekf",),
                 reward: Reward | None = None, tracked: str | None = None,
                 ticks_per_step: int | None = None, max_steps: int | None = None,
                 params: dict[str, dict[str, Any]] | None = None, render_mode: str | None = None,
                 size: tuple[int, int] = (640, 440), failed_penalty: float = 100.0):
        if not isinstance(scenario, Scenario | str | Path):
            raise ArgumentTypeError(f"scenario={short_repr(scenario)}: expected a Scenario, a name or a path")
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise UsageError(f"render_mode={short_repr(render_mode)}: expected None or one of "
                             f"{', '.join(map(repr, self.metadata['render_modes']))}")
        if isinstance(filters, str) or not isinstance(filters, Sequence) \
                or not all(isinstance(f, str) for f in filters):
            raise ArgumentTypeError(f"filters={short_repr(filters)}: expected a list of filter names, "
                                    "e.g. ['ekf']")
        if not filters:
            raise UsageError("filters=[]: expected at least one filter (the reward and the episode "
                             "follow it)")
        ticks_per_step = _whole("ticks_per_step=", ticks_per_step, MAX_TICKS_PER_STEP)
        max_steps = _whole("max_steps=", max_steps, MAX_TICKS)
        sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
        self.scenario = sc
        self.specs = list(filters)
        self.params = dict(params or {})
        self.reward_fn = reward or neg_log_det()
        self.failed_penalty = float(failed_penalty)
        fastest = min((s.period for s in sc.sensors), default=sc.dt)
        self.ticks_per_step = int(ticks_per_step or max(1, round(fastest / sc.dt)))
        self.max_steps = int(max_steps or max(1, round(sc.duration / sc.dt / self.ticks_per_step)))
        self.render_mode = render_mode
        self.size = (int(size[0]), int(size[1]))
        self.metadata = {**self.metadata, "render_fps": 1.0 / (sc.dt * self.ticks_per_step)}
        kb = sc.keyboard
        self.action_space = spaces.Box(np.array([-kb.v_max, -kb.omega_max], dtype=np.float32),
                                       np.array([kb.v_max, kb.omega_max], dtype=np.float32),
                                       dtype=np.float32)
        self._layout = observation_layout(sc)
        # Bounds far beyond any reading (clipped to them, never reached in practice): ranges
        # within twice the world's diagonal, fixes within the world grown by that much.
        xmin, ymin, xmax, ymax = sc.world.bounds
        far = 2.0 * math.hypot(xmax - xmin, ymax - ymin)
        # A scan's ranges lie in [0, the sensor's max_range].
        lim = {"seen": (0.0, 1.0), "fresh": (0.0, 1.0), "range_m": (0.0, far), "heard": (0.0, 1.0),
               "distance_m": (-far, far), "is_reference": (0.0, 1.0),
               "x_m": (xmin - far, xmax + far), "y_m": (ymin - far, ymax + far)}
        max_range = {s.name: s.max_range if math.isfinite(s.max_range) else far for s in sc.sensors}
        bounds = [(0.0, max_range[name]) if f == SCAN_RANGE else lim.get(f, (-1.0, 1.0))
                  for name, _, fields in self._layout for f in fields]
        self.observation_space = spaces.Box(np.array([b[0] for b in bounds], dtype=np.float32),
                                            np.array([b[1] for b in bounds], dtype=np.float32),
                                            dtype=np.float32)
        self.session: _Session | None = None
        self.filter_names: list[str] = []
        self.tracked = tracked
        self.steps_taken = 0
        self._drawer: Any = None
        self._run_seed: int | None = None
        self._actions: list[Control] = []   # this episode's, to rebuild it when unpickled

    # --- the Gymnasium interface --------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """A new episode. ``seed`` seeds the run itself (truth, sensors, filters: the same
        seed, the same episode for the same actions); None draws one from the env's
        generator."""
        seed = check_seed(seed, "seed=")
        if options is not None and not isinstance(options, dict):
            raise ArgumentTypeError(f"options={short_repr(options)}: expected None or a dict")
        super().reset(seed=seed)
        run_seed = int(seed) if seed is not None else int(self.np_random.integers(2**31 - 1))
        self.filter_names = list(self._start(run_seed).names)
        if self.tracked is None:
            self.tracked = self.filter_names[0]
        elif self.tracked not in self.filter_names:
            raise ValueError(f"tracked={self.tracked!r}: not one of the filters {self.filter_names}")
        self.steps_taken = 0
        obs = self.encode([])
        if self.render_mode == "human":
            self.render()
        return obs, self._info([])

    def step(self, action):
        """Apply ``action = [v, omega]`` [m/s, rad/s] for ``ticks_per_step`` ticks."""
        if self.session is None:
            raise ResetNeededError("step() before reset(): call reset() first (Gymnasium's order)")
        a = np.clip(check_action(action), self.action_space.low, self.action_space.high)
        steps = self._advance(Control(float(a[0]), float(a[1])))
        self.steps_taken += 1
        tracked = self.tracked or self.filter_names[0]  # reset() set it
        failed = self.session.runner.tracks[tracked].failed is not None
        reward = -self.failed_penalty if failed else float(self.reward_fn(self, steps))
        truncated = self.steps_taken >= self.max_steps and not failed
        obs = self.encode(steps)
        if self.render_mode == "human":
            self.render()
        return obs, reward, failed, truncated, self._info(steps)

    def render(self):
        """``rgb_array``: the frame as an (H, W, 3) uint8 array; ``human``: shown in a window."""
        if self.render_mode is None or self.session is None:
            return None
        if self._drawer is None:
            self._drawer = _Drawer(self.scenario, self.filter_names, self.size, self.render_mode)
        return self._drawer.draw(self.session, self.metadata["render_fps"])

    def close(self):
        if self._drawer is not None:
            self._drawer.close()
            self._drawer = None
        if self.session is not None:
            self.session.close()

    # --- the episode's session, and pickling -----------------------------------------------
    def _start(self, run_seed: int) -> _Session:
        if self.session is not None:
            self.session.close()
        self.session = _Session(self.scenario, self.specs, run_seed, dict(self.params))
        self._run_seed = run_seed
        self._actions = []
        return self.session

    def _advance(self, control: Control) -> list[Step]:
        assert self.session is not None
        self.session.action = control
        self._actions.append(control)
        return [self.session.tick().steps[0] for _ in range(self.ticks_per_step)]

    def __getstate__(self) -> dict[str, Any]:
        """The env without its live session (filters, generators, a hash) and window: an
        episode in progress is its seed and actions, re-simulated when unpickled."""
        state = self.__dict__.copy()
        state["session"] = None
        state["_drawer"] = None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        if self._run_seed is not None:  # the same seed and actions: the same state, bit for bit
            actions = self._actions
            self._start(self._run_seed)
            for control in actions:
                self._advance(control)

    # --- helpers --------------------------------------------------------------------------
    def estimate(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """A filter's latest estimate: mean (3,) [m, m, rad], covariance (3, 3); NaN when it
        has none (switched off)."""
        assert self.session is not None
        est = self.session.estimate(name)
        if est is None:
            return np.full(3, np.nan), np.full((3, 3), np.nan)
        return est

    def encode(self, steps: list[Step]) -> np.ndarray:
        """The observation: the latest reading of each sensor during ``steps`` (docs/gym.md)."""
        obs = np.zeros(self.observation_space.shape, dtype=np.float32)
        latest = {m.sensor: m for s in steps for m in s.measurements}
        i = 0
        for sensor, kind, fields in self._layout:
            m = latest.get(sensor)
            if kind == "beacon":
                if m is not None:
                    slot = {int(b): k for k, b in enumerate(self._beacon_ids)}
                    for row, bid in zip(m.z, m.beacon_ids, strict=True):
                        j = i + len(BEACON_SLOT) * slot[int(bid)]
                        rng = float(row[0]) if m.kind == "range_bearing" else 0.0
                        b = float(row[-1])
                        obs[j:j + 4] = (1.0, rng, math.cos(b), math.sin(b))
            elif kind == "distance":
                if m is not None:
                    slot = {int(b): k for k, b in enumerate(self._beacon_ids)}
                    ids = [int(b) for b in m.beacon_ids]
                    values = [0.0, *m.z[:, 0].tolist()] if m.kind == "tdoa" else m.z[:, 0].tolist()
                    for k, (bid, v) in enumerate(zip(ids, values, strict=True)):
                        j = i + len(DISTANCE_SLOT) * slot[bid]
                        obs[j:j + 3] = (1.0, v, 1.0 if (m.kind == "tdoa" and k == 0) else 0.0)
            elif kind == "scan":
                if m is not None:   # fresh, then the ranges [m] in the sensor's beam order
                    obs[i] = 1.0
                    obs[i + 1:i + len(fields)] = m.z[:, 0]
            elif m is not None:
                z = m.z[0]
                th = float(z[2]) if m.kind == "pose" else None
                obs[i:i + 5] = (1.0, z[0], z[1], math.cos(th) if th is not None else 0.0,
                                math.sin(th) if th is not None else 0.0)
            i += len(fields)
        return np.clip(obs, self.observation_space.low, self.observation_space.high)

    @property
    def _beacon_ids(self) -> list[int]:
        return [b.id for b in self.scenario.world.beacons]

    def _info(self, steps: list[Step]) -> dict[str, Any]:
        assert self.session is not None
        mean, cov = self.estimate(self.tracked or self.filter_names[0])
        return {"time": self.session.time, "true_pose": self.session.true_pose.copy(),
                "estimate": np.array(mean), "cov": np.array(cov),
                "events": [e.kind for s in steps for e in s.events]}


def observation_layout(scenario: Scenario) -> list[tuple[str, str, tuple[str, ...]]]:
    """(sensor, "beacon", "scan" or "fix", field names) per block of the observation, in
    order: a beacon sensor's block is one :data:`BEACON_SLOT` per beacon of the map (in map
    order), a range finder's is :data:`SCAN_FRESH` then ``n_beams`` :data:`SCAN_RANGE`, a
    fix sensor's block is one :data:`FIX_SLOT`."""
    out = []
    for s in scenario.sensors:
        if s.kind in ("bearing", "range_bearing"):
            fields = tuple(f"{s.name}.B{b.id}.{f}" for b in scenario.world.beacons for f in BEACON_SLOT)
            out.append((s.name, "beacon", tuple(f.rpartition(".")[2] for f in fields)))
        elif s.kind in DISTANCE_KINDS:
            out.append((s.name, "distance", DISTANCE_SLOT * len(scenario.world.beacons)))
        elif is_scan(s.kind):
            out.append((s.name, "scan", (SCAN_FRESH,) + (SCAN_RANGE,) * s.n_beams))
        else:
            out.append((s.name, "fix", FIX_SLOT))
    return out


def observation_names(scenario: Scenario) -> list[str]:
    """One name per number of the observation, e.g. ``beacons.B3.range_m`` or
    ``laser.beam7.range_m``."""
    names = []
    for s in scenario.sensors:
        if s.kind in ("bearing", "range_bearing"):
            names += [f"{s.name}.B{b.id}.{f}" for b in scenario.world.beacons for f in BEACON_SLOT]
        elif s.kind in DISTANCE_KINDS:
            names += [f"{s.name}.B{b.id}.{f}" for b in scenario.world.beacons for f in DISTANCE_SLOT]
        elif is_scan(s.kind):
            names += [f"{s.name}.{SCAN_FRESH}"] + [f"{s.name}.beam{k}.range_m" for k in range(s.n_beams)]
        else:
            names += [f"{s.name}.{f}" for f in FIX_SLOT]
    return names


class _Drawer:
    """The window's renderer on an off-screen surface (or the window, for ``human``)."""

    def __init__(self, scenario: Scenario, names: list[str], size: tuple[int, int], mode: str):
        import pygame

        from beacon_sim.app.assets import load_fonts
        from beacon_sim.app.palette import filter_styles
        from beacon_sim.app.render import ShowOptions, View, WorldRenderer

        self.pygame = pygame
        pygame.font.init()
        self.mode = mode
        if mode == "human":
            pygame.display.init()
            self.surface = pygame.display.set_mode(size)
            pygame.display.set_caption(f"beacon-sim gym: {scenario.name}")
            self.clock = pygame.time.Clock()
        else:
            self.surface = pygame.Surface(size)
        styles = filter_styles(names)
        self.colours = {n: c for n, (c, _) in styles.items()}
        self.dashes = {n: d for n, (_, d) in styles.items()}
        self.renderer = WorldRenderer(load_fonts(size[1]))
        self.view = View(scenario.world.bounds, (0, 0, size[0], size[1]))
        self.show = ShowOptions()

    def draw(self, session: Session, fps: float):
        self.renderer.draw(self.surface, self.view, session, self.colours, self.show,
                           dashes=self.dashes)
        if self.mode == "human":
            self.pygame.event.pump()
            self.pygame.display.flip()
            self.clock.tick(fps)
            return None
        return np.transpose(self.pygame.surfarray.array3d(self.surface), (1, 0, 2)).copy()

    def close(self) -> None:
        if self.mode == "human":
            self.pygame.display.quit()


#: The default env's episode length in steps (``default`` scenario: 60 s of 2 ticks of 50 ms),
#: the registered spec's ``max_episode_steps``; another scenario passes its own to ``make``.
DEFAULT_MAX_STEPS = 1200

if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="beacon_sim.gym:BeaconEnv",
                       max_episode_steps=DEFAULT_MAX_STEPS)
