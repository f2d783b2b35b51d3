"""A task as one typed unit: what the env, training, evaluation, registration and the bench read.

Each robot package exports its TaskSpec(s) and registers them (`register_tasks`) when imported.
A spec names its gymnasium env (id, entry point, max_episode_steps), its frozen params dataclass
and default YAML (`<package>/config/<name>.yaml`), its Q-learning state key, its results folder,
its reward topics, the robot (URDF and sim config, found through ROS package paths; its joint limits
read from the URDF), and the per-episode metrics that training logs and evaluation reports.
"""
from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, Protocol, TypeVar

import gymnasium

from pybullet_sim.urdf import UrdfJoint, parse_urdf_joints

from .params import ParamError, TaskParams, load_yaml_file

P = TypeVar("P", bound=TaskParams)
MetricValue = float | bool


class ResourceError(RuntimeError):
    """A ROS package (URDF, config) cannot be found."""


@functools.cache
def package_path(package: str) -> Path:
    """The directory of a ROS package (source or install space), found through ROS_PACKAGE_PATH."""
    import rospkg
    try:
        return Path(rospkg.RosPack().get_path(package))
    except rospkg.ResourceNotFound:
        raise ResourceError(f"ROS package {package!r} not found on ROS_PACKAGE_PATH; source the workspace "
                            f"(./ws exec ..., or `source devel/setup.bash`)") from None


class StateKey(Protocol):
    """Observation -> Q-table state key; to_dict() is saved with the table so that a mismatch shows."""

    def key(self, observation: Any) -> str: ...

    def to_dict(self) -> dict[str, Any]: ...


@dataclass(frozen=True)
class RobotSpec:
    """A robot of the sim: its URDF and its config/<robot>_sim.yaml, both in its description package."""

    description_package: str
    urdf: str            # relative to the package
    sim_config: str      # relative to the package
    sim_launch: str      # how a user starts its sim, for error messages

    @property
    def urdf_path(self) -> Path:
        return package_path(self.description_package) / self.urdf

    @property
    def sim_config_path(self) -> Path:
        return package_path(self.description_package) / self.sim_config

    def joints(self) -> Mapping[str, UrdfJoint]:
        """The URDF's joints by name, with their <limit>s (what the sim clamps commands to)."""
        return _urdf_joints(self.urdf_path)

    def joint_limits(self, names: Sequence[str]) -> tuple[tuple[float, float], ...]:
        """(lower, upper) position limits of the named joints, from the URDF."""
        joints = self.joints()
        return tuple((joints[name].lower, joints[name].upper) for name in names)


@functools.cache
def _urdf_joints(path: Path) -> Mapping[str, UrdfJoint]:
    return parse_urdf_joints(path.read_text(), str(path))[1]


@dataclass(frozen=True)
class Episode:
    """What a finished episode hands to a task's metrics."""

    steps: int
    return_: float
    terminated: bool
    duration: float               # sim seconds
    info: Mapping[str, Any]       # the last step's info


def episode_duration(info: Mapping[str, Any], steps: int, running_step: float) -> float:
    """An episode's sim seconds: steps x running_step, or the last info's "episode_time" where a task's steps
    differ in length (the monoped's hop-level task: one step per hop)."""
    return float(info.get("episode_time", steps * running_step))


def play_episode(env: gymnasium.Env[Any, Any], act: Callable[[Any], Any], running_step: float, *,
                 seed: int | None = None, max_steps: int | None = None) -> Episode:
    """One episode of `act` (observation -> action) from env.reset(seed=seed), until it terminates, is truncated
    or has taken `max_steps` steps (None: the env's own limit). No learning: evaluation's and the checks' loop."""
    observation, _ = env.reset(seed=seed)
    total, steps, terminated = 0.0, 0, False
    info: Mapping[str, Any] = {}
    while max_steps is None or steps < max_steps:
        observation, reward, terminated, truncated, info = env.step(act(observation))
        total, steps = total + float(reward), steps + 1
        if terminated or truncated:
            break
    return Episode(steps=steps, return_=total, terminated=terminated,
                   duration=episode_duration(info, steps, running_step), info=info)


@dataclass(frozen=True)
class TaskSpec(Generic[P]):
    name: str                                   # `task:=` in the launch files; the default YAML is config/<name>.yaml
    env_id: str
    entry_point: str                            # "module:EnvClass"
    package: str                                # the robot's training package
    robot: RobotSpec
    params_type: type[P]
    params_namespace: str                       # where the YAML's keys live on the parameter server
    state_key: Callable[[P], StateKey]
    results_name: str                           # runs go to <results_dir>/<results_name>/
    reward_topic: str
    episode_reward_topic: str
    publish_cumulated_reward: bool              # the hopper tutorial publishes the running sum each step
    max_episode_steps: int                      # registered; equals the default YAML's nsteps
    metrics: Callable[[Episode], dict[str, MetricValue]]   # per episode (also of an empty one); bools are rates
    headline_metric: str                        # the metric progress lines show
    eval_horizon_s: float                       # evaluate.py's default horizon, in sim seconds
    curve_metrics: tuple[str, ...] = ()         # metrics learning_curve.png plots below the headline one
    former_env_ids: tuple[str, ...] = ()        # ids it had before a rename: registered too, found by find_task

    @property
    def env_ids(self) -> tuple[str, ...]:
        """Its env id, then its former ones."""
        return (self.env_id, *self.former_env_ids)

    @property
    def metric_names(self) -> tuple[str, ...]:
        """The names `metrics` returns (read from an empty episode)."""
        return tuple(self.metrics(Episode(steps=0, return_=0.0, terminated=False, duration=0.0, info={})))

    @property
    def config_path(self) -> Path:
        return package_path(self.package) / "config" / f"{self.name}.yaml"

    def params_from_document(self, document: Mapping[str, Any], source: str, strict: bool = False) -> P:
        """The params of a YAML document laid out as on the parameter server (under params_namespace); `strict`:
        a key under it that the params do not declare is refused (Params.from_mapping)."""
        values: Any = document
        for part in self.params_namespace.strip("/").split("/"):
            if part:
                values = values.get(part, {}) if isinstance(values, Mapping) else {}
        return self.params_type.from_mapping(values, source, strict=strict)

    def load_params(self, path: Path) -> P:
        """The params of a config file, every key of it known (ParamError naming an unknown one and the file)."""
        return self.params_from_document(load_yaml_file(path), str(path), strict=True)

    def default_params(self) -> P:
        return self.load_params(self.config_path)


TASKS: dict[str, TaskSpec[Any]] = {}


def register_tasks(*specs: TaskSpec[Any]) -> None:
    """Register each spec's env, under its env id and its former ones, with gymnasium (with its max_episode_steps)
    and in TASKS."""
    for spec in specs:
        for env_id in spec.env_ids:
            TASKS[env_id] = spec
            if env_id not in gymnasium.registry:
                gymnasium.register(id=env_id, entry_point=spec.entry_point, max_episode_steps=spec.max_episode_steps)


def find_task(tasks: list[TaskSpec[Any]], name: str) -> TaskSpec[Any]:
    """The task called `name` (its name, env id or a former env id) among `tasks`."""
    for spec in tasks:
        if name == spec.name or name in spec.env_ids:
            return spec
    known = ", ".join(spec.name for spec in tasks)
    raise ParamError(f"unknown task {name!r} (known: {known})")


def make_env(spec: TaskSpec[P], *, params: P | None = None, backend: Any = "direct", seed: int | None = None,
             max_episode_steps: int | None = None, **kwargs: Any) -> gymnasium.Env[Any, Any]:
    """gymnasium.make of the task, truncated at params.nsteps unless `max_episode_steps` says otherwise (the env's
    params then have that nsteps too: a task whose steps differ in length truncates by sim time from it)."""
    params = params if params is not None else spec.default_params()
    if max_episode_steps is not None and max_episode_steps != params.nsteps:
        params = params.with_changes("max_episode_steps", nsteps=max_episode_steps)
    return gymnasium.make(spec.env_id, max_episode_steps=params.nsteps, backend=backend,
                          params=params, seed=seed, **kwargs)
