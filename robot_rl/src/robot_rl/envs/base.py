"""Gymnasium env base shared by every task: lockstep steps over a Backend, task code in subclass hooks.

A step is: the task turns the action into controller commands, the backend advances exactly
`running_step` of sim time, and the task turns the readings into observation, reward terms and
termination. No wall-clock sleeps and no wait-until-the-robot-gets-there loops: a step always lasts
running_step of sim time. `reset(seed=...)` also restarts sim time and the sensor noise
(reset_simulation), so a seeded reset makes the episode reproducible; an unseeded reset uses
reset_world, as openai_ros does for these robots. A robot spawned above the ground can be given
`settle_time` of sim time to land (with its reset commands) before the first observation, and a task
can put the robot in a start pose of its own after the reset (`_start_placement`, drawn from the env's
seeded np_random); the first observation then comes after at least one physics step.

The reward is the sum of the task's named terms, and every term is in `info` as `reward_<name>`
(Gymnasium's hopper_v5 convention). Truncation is gymnasium's TimeLimit (registered with each task's
max_episode_steps; `robot_rl.task.make_env` sets it to the params' nsteps), not the env's business.

Rendering (gymnasium's conventions, so RecordVideo and robot_rl.runs.video work on every task):
render_mode "rgb_array" makes render() return the frame of the sim's camera that follows the robot
(render_height x render_width x 3, uint8; over ROS from the sim node's ~render service, so the env
needs no physics of its own); "human" opens PyBullet's window on the direct backend (the camera
follows the robot, and each step waits so that sim time runs no faster than wall time); over ROS the
sim node's window (gui:=true) or rviz (rviz:=true) shows the robot. metadata["render_fps"] is
1 / running_step: one frame per control period. A task whose env step runs several control periods
(`multi_period_steps`, e.g. one step a hop) calls every function in `period_hooks` after each period,
so that a recorder can take frames in real time within a step, and runs each period through `_run_period`.

Pushes (params push_speed > 0, robot_rl.envs.pushes): before a control period in which a push's time falls, the
backend kicks the base horizontally; the times and directions come from the last seeded reset's seed and the
episodes since it, so training and evaluate.py --push share one seeded schedule on either backend.

The attitude assist (params attitude_assist with a stiffness or a damping): the env sets the sim's torque that
pulls the base upright at the params' scale when it starts, and at any other with `set_assist_scale` (a run's
curriculum, robot_rl.runs.curriculum); over ROS the sim gets its own assist back when the env closes.
"""
from __future__ import annotations

import abc
import time
from collections.abc import Callable
from typing import Any, ClassVar, Generic, TypeVar

import gymnasium
import numpy as np
from gymnasium import spaces

from pybullet_sim.readings import FrameState

from ..params import TaskParams
from ..task import TaskSpec
from .backends.base import Backend, Readings
from .backends.factory import make_backend
from .pushes import PushPlan

P = TypeVar("P", bound=TaskParams)
MAX_PHYSICS_STEPS = 100_000  # pybullet_sim's Step.MAX_STEPS: the most one lockstep step may advance
StepOutcome = tuple[dict[str, float], bool, dict[str, Any]]   # reward terms, terminated, extra info
Placement = tuple[FrameState, dict[str, float]]   # the base's pose and twist (world frame), joint positions by name


class RobotEnv(gymnasium.Env[np.ndarray, Any], Generic[P], abc.ABC):
    """A task's env: subclasses set `task` and implement the hooks below."""

    task: ClassVar[TaskSpec[Any]]
    multi_period_steps: ClassVar[bool] = False  # True: a step runs several control periods, calling period_hooks
    metadata: dict[str, Any] = {"render_modes": ["rgb_array", "human"]}  # + render_fps, per instance
    action_space: spaces.Discrete | spaces.Box
    observation_space: spaces.Box

    def __init__(self, backend: str | Backend = "ros", params: P | None = None, seed: int | None = None,
                 ros_timeout: float = 10.0, render_mode: str | None = None, render_width: int = 320,
                 render_height: int = 240):
        """`params`: the task's validated params (default: its config/<task>.yaml). `backend`: "ros" (a
        running sim node), "direct" (an in-process World seeded with `seed`) or a Backend. `render_mode`:
        None, "rgb_array" (frames of render_width x render_height pixels) or "human"."""
        task = self.task
        self.params: P = params if params is not None else task.default_params()
        if not isinstance(self.params, task.params_type):
            raise TypeError(f"params must be {task.params_type.__name__}, got {type(self.params).__name__}")
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        if not all(isinstance(v, int) and v > 0 for v in (render_width, render_height)):
            raise ValueError(f"render_width and render_height must be positive whole pixels, got {render_width!r} and "
                             f"{render_height!r}")
        self.render_mode, self.render_width, self.render_height = render_mode, render_width, render_height
        self._wall_origin: tuple[float, float] | None = None  # human mode: (wall, sim) time at the episode start
        self.backend = make_backend(backend, task.robot, seed=seed, timeout=ros_timeout, gui=render_mode == "human")
        time_step = self.backend.time_step
        if self.params.running_step < time_step:
            self.backend.close()
            raise ValueError(f"running_step {self.params.running_step} s is shorter than one physics step "
                             f"({time_step} s)")
        self.running_step = self.params.running_step
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.running_step}
        self.physics_steps = round(self.running_step / time_step)
        if self.physics_steps > MAX_PHYSICS_STEPS:
            self.backend.close()
            raise ValueError(f"running_step {self.running_step} s is {self.physics_steps} physics steps of {time_step} "
                             f"s, more than the {MAX_PHYSICS_STEPS} one sim step may take")
        self.settle_steps = round(self._settle_time() / time_step)
        self.readings: Readings | None = None
        self.period_hooks: list[Callable[[], None]] = []
        interval = self.params.push_interval
        self.pushes = PushPlan(self.params.push_speed, (interval.low, interval.high))
        self.closed = False
        if self.params.attitude_assist.active:
            try:
                self.set_assist_scale(self.params.attitude_assist.scale)
            except BaseException:
                self.backend.close()
                raise
        self.action_space, self.observation_space = self._spaces()

    # -- task hooks -----------------------------------------------------------------------------
    @abc.abstractmethod
    def _spaces(self) -> tuple[spaces.Discrete | spaces.Box, spaces.Box]:
        """(action_space, observation_space), from self.params: Discrete actions are ints, Box ones arrays."""

    def _settle_time(self) -> float:
        """Sim seconds the robot gets to land after a reset, before the first observation."""
        return 0.0

    def _start_placement(self) -> Placement | None:
        """Where the robot starts after a reset, drawn with self.np_random; None: where the reset left it."""
        return None

    @abc.abstractmethod
    def _reset_commands(self) -> None:
        """Command the controllers' start values (before the robot settles)."""

    @abc.abstractmethod
    def _start_episode(self, readings: Readings) -> None:
        """Reset the task's own state (start position...) from the first readings of the episode."""

    @abc.abstractmethod
    def _apply_action(self, action: Any, readings: Readings) -> None:
        """Turn the action into controller commands with self.backend.set_command; `readings` are the latest."""

    @abc.abstractmethod
    def _observe(self, readings: Readings) -> np.ndarray:
        """The observation (inside observation_space) from the readings."""

    @abc.abstractmethod
    def _reward_and_termination(self, observation: np.ndarray, readings: Readings) -> StepOutcome:
        """(reward terms by name, terminated, extra info) for the step that produced these readings."""

    # -- gymnasium API --------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        self._check_open()
        super().reset(seed=seed)
        self.readings = self.backend.reset(restart_time=seed is not None)
        placement = self._start_placement()
        if placement is not None:
            self.backend.place(*placement)
        self._reset_commands()
        settle_steps = max(self.settle_steps, 1 if placement is not None else 0)  # readings of the new pose
        if settle_steps:
            self.readings = self.backend.step(settle_steps)
        self._start_episode(self.readings)
        self.pushes.start_episode(self.readings.stamp, seed)
        if self.render_mode == "human":
            self._wall_origin = None
            self.render()
        return self._observe(self.readings), {"sim_time": self.readings.stamp}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self._check_open()
        if self.readings is None:
            raise gymnasium.error.ResetNeeded("call reset() before step()")
        space = self.action_space
        if isinstance(space, spaces.Discrete):
            # A direct range check first: Discrete.contains costs as much as a tenth of a lockstep exchange.
            if not (isinstance(action, (int, np.integer)) and 0 <= action < int(space.n)) \
                    and not space.contains(action):  # e.g. SB3's predict(): a 0-d integer array
                raise ValueError(f"action {action!r} is not in {space}")
            action = int(action)
        else:
            action = np.asarray(action, dtype=space.dtype)
            if not space.contains(action):
                raise ValueError(f"action {action!r} is not in {space}")
        self._apply_action(action, self.readings)
        self.readings = readings = self._run_period()
        observation = self._observe(readings)
        terms, terminated, info = self._reward_and_termination(observation, readings)
        for name, value in terms.items():
            info[f"reward_{name}"] = value
        info["sim_time"] = readings.stamp
        if self.render_mode == "human":
            self.render()
        return observation, float(sum(terms.values())), terminated, False, info

    def _run_period(self) -> Readings:
        """One control period: the pushes due (params' push_speed), then running_step of sim time; its readings."""
        assert self.readings is not None
        for kick in self.pushes.due(self.readings.stamp):
            self.backend.kick(kick)
        return self.backend.step(self.physics_steps)

    def set_assist_scale(self, scale: float) -> None:
        """The sim's attitude assist from the next step on: the params' stiffness and damping times `scale`."""
        self._check_open()
        assist = self.params.attitude_assist
        if not (0.0 <= scale <= 1.0):
            raise ValueError(f"the attitude assist's scale must be from 0 to 1, got {scale!r}")
        self.backend.set_attitude_assist(scale * assist.stiffness, scale * assist.damping)

    def render(self) -> np.ndarray | None:  # type: ignore[override]  # gymnasium 1.2: an unbound RenderFrame
        """rgb_array: the current frame; human: update the view and keep sim time no faster than wall time."""
        self._check_open()
        if self.render_mode == "rgb_array":
            return self.backend.render(self.render_width, self.render_height)
        if self.render_mode == "human":
            self.backend.show()
            stamp, now = (self.readings.stamp if self.readings else 0.0), time.monotonic()
            if self._wall_origin is None:
                self._wall_origin = (now, stamp)
            ahead = (stamp - self._wall_origin[1]) - (now - self._wall_origin[0])
            if ahead > 0.0:
                time.sleep(ahead)  # a person watches: sim time at most as fast as wall time
            return None
        gymnasium.logger.warn("render() without a render_mode: make the env with render_mode='rgb_array' or 'human'")
        return None

    def close(self) -> None:
        """Release the backend (over ROS: the sim is left as it was found); a second close does nothing."""
        if not self.closed:
            self.closed = True
            self.backend.close()

    def _check_open(self) -> None:
        if self.closed:
            raise gymnasium.error.ClosedEnvironmentError(f"{self.task.env_id}: the env is closed: make a new one")


def assist_setter(env: Any) -> Callable[[float], None] | None:
    """`env`'s set_assist_scale if it is one RobotEnv (wrapped or not); None for a vector of envs."""
    unwrapped = getattr(env, "unwrapped", None)
    return unwrapped.set_assist_scale if isinstance(unwrapped, RobotEnv) else None
