"""Evaluate a trained run: its greedy policy, then a uniformly random one, on the run's own task.

  evaluate.py --qtable RUN [--episodes N] [--horizon-s S] [--backend direct|ros] [--seed S]
              [--initial-tilt LOW HIGH] [--push V] [--assist S]
              [--video PATH.mp4 [--video-episodes N] [--video-size WxH] [--slow-motion K]]
  evaluate.py --policy NAME [--task TASK] [--speed M_S] [the options above but --qtable and --video]
  evaluate.py --policy constant --action N [--task TASK] [the same options]

RUN (also --run) is a run folder (training_results/<task>/<run>, or its `latest` link) or its checkpoint:
qtable.json of tabular Q-learning (or qtable_best.json, the best of its checked tables: the params' selection), or
agent.json of a deep agent (its greedy policy is the SB3 model's deterministic action, the model rebuilt from
agent.json and its weights loaded from model.zip; needs requirements-deep.txt: ./ws setup deep). The checkpoint
names the task (and a deep run's agent, see robot_rl.agents), the run's params.yaml gives its parameters. Each
episode lasts until the task terminates it or `--horizon-s` seconds of sim time have passed (default: the task's).
A task whose params have `initial_tilt` (the monoped's) starts every episode leaning by a random angle in
`--initial-tilt LOW HIGH` rad (default 0.02 0.05; `0 0`: upright) in a random direction, drawn from the
evaluation seed, so that no policy can lean on a perfectly upright start. The last output line is one
JSON object: {"task", "episodes", "horizon_s", "seed", "initial_tilt", "greedy": {...}, "random": {...}},
each policy with mean_return and the task's metrics (`mean_<metric>`, `<metric>_rate`); "initial_tilt"
is [LOW, HIGH], or null for a task without it.
`--policy NAME` evaluates instead a hand-written policy that the robot's package offers (the monoped's
`controller`, hopper_training.controller_policy), commanded `--speed` m/s along +x, on `--task`'s default
params as that policy needs them; its JSON has "policy": NAME and NAME: {...} with the keys of "greedy".
`--policy constant --action N`, on every robot, takes action N every step (Discrete actions; a Box action as
comma-separated values, e.g. `--action=-0.5,0,0`, with `=` when the first is negative):
the trivial baselines a learned policy must beat besides random ones; its JSON adds "action": N.
`--push V` kicks the robot's base V m/s horizontally in a random direction at random times, one every 1-3 s of
sim time, for every policy: the env's own pushes (params push_speed V, push_interval 1-3 s;
robot_rl.envs.pushes: drawn from the evaluation seed and the episode's number); the JSON adds "push": V.
Without it a run trained with pushes is evaluated without them.
`--assist S` holds the run's attitude assist (params attitude_assist, the sim's torque that pulls the base upright,
robot_rl.runs.curriculum) at scale S from 0 to 1 for every policy; the JSON adds "assist": {"scale", "stiffness",
"damping"}. Without it (or with 0) a run trained with the assist is evaluated without it.
`--video` records the first `--video-episodes` (3) greedy episodes to an mp4 (robot_rl.runs.video: real
time, or `--slow-motion K` times slower, at most 30 frames/s, from the robot's camera of its sim config) and
adds "video": {"path", "episodes", "frames", "fps", "slow_motion"} to the JSON; recording changes none of the
numbers.
The direct backend (default) needs nothing running; `--backend ros` needs the task's sim node.
A lost sim, or a sim state that is no longer finite, ends it with one line and exit code 1 (either backend), as
does a deep run's model.zip that is not the one its agent.json recorded (robot_rl.agents.sb3.policy). A bad option
is one line and exit code 2: `--seed` in [0, 2**31 - 1] (a training seed's range), `--horizon-s` finite in
(0, MAX_HORIZON_S], `--speed` finite, `--video` an .mp4 file, not a folder.
Every robot package's evaluate.py is this, for its own tasks.
"""
from __future__ import annotations

import argparse
import json
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from pybullet_sim.ros.client import SimConnectionError

from .agents.registry import AgentSpec, agent_of, checkpoint_of
from .envs.backends.base import SimStateError
from .envs.backends.factory import over_ros
from .envs.backends.ros import init_ros_node
from .envs.pushes import PUSH_GAP_S
from .params import MAX_SEED, ParamError
from .policies import ScriptedPolicy, constant_policy, random_actions
from .runs.loaded import LoadedRun
from .runs.results import RunDirectory, RunFileError, aggregate
from .runs.video import VideoRecorder
from .task import TaskSpec, find_task, make_env, play_episode

MAX_VIDEO_SIDE = 4096
MAX_HORIZON_S = 86400.0   # s of sim time per episode at most: a day
EVAL_INITIAL_TILT = (0.02, 0.05)  # rad: evaluation episodes start leaning this much, where the task can


def with_assist(params: Any, scale: float, source: str = "--assist") -> Any:
    """`params` with the attitude assist held at `scale` of the params' gains (0: none, whatever the run trained
    with); ParamError for a scale > 0 where the params have no assist."""
    assist = params.attitude_assist
    if scale > 0.0 and not assist.active:
        raise ParamError(f"{source}: the run has no attitude assist (its params' attitude_assist has no stiffness "
                         f"and no damping)")
    if not assist.active or (scale == assist.scale and not assist.adapt_every):
        return params
    held = {**assist.to_mapping(), "scale": scale, "adapt_every": 0, "free_share": 0.0}
    if scale == 0.0:
        held.update(stiffness=0.0, damping=0.0, scale=1.0)
    return params.with_changes(source, attitude_assist=held)


def assist_report(params: Any) -> dict[str, Any]:
    """The JSON's "assist" entry for params held by with_assist (empty without an assist)."""
    assist = params.attitude_assist
    return {"assist": {"scale": assist.scale, "stiffness": assist.stiffness, "damping": assist.damping}} \
        if assist.active else {}


def with_push(params: Any, push: float, source: str = "--push") -> Any:
    """`params` with the env's pushes set to `push` m/s (0: none) at evaluation's standard interval PUSH_GAP_S,
    whatever the run trained with (robot_rl.envs.pushes)."""
    interval = {"low": PUSH_GAP_S[0], "high": PUSH_GAP_S[1]}
    if params.push_speed == push and (params.push_interval.low, params.push_interval.high) == PUSH_GAP_S:
        return params
    return params.with_changes(source, push_speed=push, push_interval=interval)


class TrainedRun(LoadedRun):
    """A run's agent, task, params and greedy policy, checked against each other. `path`: a run folder
    or its checkpoint file."""

    agent: AgentSpec

    def __init__(self, path: Path, tasks: Sequence[TaskSpec[Any]]):
        path = checkpoint_of(path) if path.is_dir() else path
        checkpoint = RunDirectory(path.parent, path.name).load_checkpoint()
        try:
            agent = agent_of(checkpoint)
            task = find_task(list(tasks), checkpoint["task"])
        except (KeyError, TypeError) as error:
            raise ValueError(f"{path}: not a training checkpoint (missing {error})") from None
        params_file = path.with_name("params.yaml")
        try:
            document = yaml.safe_load(params_file.read_text(encoding="utf-8"))
        except (OSError, yaml.YAMLError) as error:
            raise ValueError(f"{params_file}: {error}") from None
        params = task.params_type.from_mapping(document or {}, str(params_file))
        super().__init__(path, agent, task, params_file, params)
        self._policy = agent.greedy_policy(self, checkpoint)

    def policy(self, env: Any, seed: int) -> Callable[[np.ndarray], int]:
        """The greedy policy (tie breaks seeded with `seed`); `env` shapes a deep agent's model."""
        return self._policy(env, seed)


@dataclass(frozen=True)
class VideoRequest:
    """Record the first `episodes` greedy episodes to `path` (an .mp4), frames of width x height pixels."""

    path: Path
    episodes: int = 3
    width: int = 320
    height: int = 240
    slow_motion: float = 1.0  # the video plays this many times slower than real time


def run_episodes(env: Any, policy: Callable[[np.ndarray], Any], episodes: int, task: TaskSpec[Any],
                 running_step: float) -> dict[str, float | None]:
    """Mean return and the task's metrics of `episodes` episodes of `policy`."""
    returns: list[float] = []
    metrics: dict[str, list[Any]] = {name: [] for name in task.metric_names}
    reset_policy = getattr(policy, "reset", None)
    for _ in range(episodes):
        if reset_policy is not None:
            reset_policy()
        episode = play_episode(env, policy, running_step)
        returns.append(episode.return_)
        for name, value in task.metrics(episode).items():
            metrics[name].append(value)
    return {**aggregate({"return": returns}), **aggregate(metrics)}


def default_initial_tilt(params: Any) -> tuple[float, float] | None:
    """How evaluate.py starts episodes by default: leaning EVAL_INITIAL_TILT where the task can (its params
    have initial_tilt), whatever the run trained from; None where it cannot."""
    return EVAL_INITIAL_TILT if hasattr(params, "initial_tilt") else None


def with_initial_tilt(params: Any, tilt: tuple[float, float] | None, source: str) -> Any:
    """`params` with initial_tilt set to `tilt` (LOW, HIGH), if the task has one; None leaves them as they are."""
    if tilt is None:
        return params
    return params.with_changes(source, initial_tilt={"low": tilt[0], "high": tilt[1]})


def evaluate(run: TrainedRun, episodes: int, horizon_s: float, backend: str, seed: int,
             video: VideoRequest | None = None, initial_tilt: tuple[float, float] | None = None,
             push: float = 0.0, assist: float = 0.0) -> dict[str, Any]:
    """Greedy, then seeded uniformly random, `episodes` each, from a seeded first reset; `video` records
    the first greedy episodes; `initial_tilt` (LOW, HIGH rad) replaces the run's params' (None: the run's);
    `push` > 0: kicks of that many m/s (with_push; 0: none, even for a run trained with pushes); `assist`: the
    run's attitude assist at that scale (with_assist; 0: none)."""
    params = with_assist(with_push(with_initial_tilt(run.params, initial_tilt, "--initial-tilt"), push), assist)
    steps = max(1, round(horizon_s / params.running_step))
    rendering = {} if video is None else {"render_mode": "rgb_array", "render_width": video.width,
                                          "render_height": video.height}
    env = make_env(run.task, params=params, backend=backend, seed=seed, max_episode_steps=steps, **rendering)
    recorder = None if video is None else VideoRecorder(env, video.path, video.episodes,
                                                      slow_motion=video.slow_motion)
    rng = np.random.default_rng(seed)
    try:
        policy = run.policy(env, seed)
        env.reset(seed=seed)
        greedy = run_episodes(recorder or env, policy, episodes, run.task, run.params.running_step)
        random_policy = run_episodes(env, random_actions(env.action_space, rng), episodes, run.task,
                                     run.params.running_step)
    finally:
        (recorder or env).close()
    tilt = getattr(params, "initial_tilt", None)
    report = {"task": run.task.env_id, "episodes": episodes, "horizon_s": steps * params.running_step,
              "seed": seed, "initial_tilt": None if tilt is None else [tilt.low, tilt.high], "greedy": greedy,
              "random": random_policy}
    if push > 0.0:
        report["push"] = push
    report.update(assist_report(params))
    if recorder is not None:
        report["video"] = {"path": str(recorder.path), "episodes": recorder.episodes_recorded,
                           "frames": recorder.frames, "fps": recorder.fps, "slow_motion": recorder.slow_motion}
    return report


def evaluate_scripted(task: TaskSpec[Any], name: str, scripted: ScriptedPolicy, params: Any, episodes: int,
                      horizon_s: float, backend: str, seed: int, speed: float, push: float = 0.0,
                      assist: float = 0.0) -> dict[str, Any]:
    """`episodes` episodes of the scripted policy `name` on `params` (as scripted.env_params made them),
    from a seeded first reset."""
    params = with_assist(with_push(params, push), assist)
    steps = max(1, round(horizon_s / params.running_step))
    env = make_env(task, params=params, backend=backend, seed=seed, max_episode_steps=steps)
    try:
        policy = scripted.build(env, speed)
        env.reset(seed=seed)
        figures = run_episodes(env, policy, episodes, task, params.running_step)
    finally:
        env.close()
    tilt = getattr(params, "initial_tilt", None)
    return {"task": task.env_id, "episodes": episodes, "horizon_s": steps * params.running_step, "seed": seed,
            "initial_tilt": None if tilt is None else [tilt.low, tilt.high], "policy": name, "speed": speed,
            name: figures, **({"push": push} if push > 0.0 else {}), **assist_report(params)}


def video_size(text: str) -> tuple[int, int]:
    """WxH (even numbers of pixels, H.264's rule) from the command line."""
    match = re.fullmatch(r"(\d+)x(\d+)", text)
    if not match or not all(0 < int(v) <= MAX_VIDEO_SIDE and int(v) % 2 == 0 for v in match.groups()):
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT in even pixels from 2 to {MAX_VIDEO_SIDE}, "
                                         f"e.g. 320x240")
    return int(match[1]), int(match[2])


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line (no usage above it), exit code 2 as argparse's."""

    def error(self, message: str) -> Any:  # argparse's signature is NoReturn
        self.exit(2, f"{self.prog}: error: {message} ({self.prog} --help lists the options)\n")


def finite_float(text: str) -> float:
    """A finite number from the command line (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def main(argv: Sequence[str], tasks: Sequence[TaskSpec[Any]], node_name: str,
         policies: Mapping[str, ScriptedPolicy] | None = None) -> int:
    """evaluate.py of a robot package: its `tasks`, the hand-written `policies` it offers, and `constant`, action
    --action N every step (--policy)."""
    policies = policies or {}
    parser = OneLineParser(prog="evaluate.py", description=__doc__.splitlines()[0])
    parser.add_argument("--qtable", "--run", dest="run", type=Path,
                        help="a run folder, or its qtable.json, qtable_best.json or agent.json (the greedy policy)")
    parser.add_argument("--policy", choices=("greedy", *policies, "constant"), default="greedy",
                        help="greedy: the trained run's (default); a hand-written policy of the robot's package; or "
                             "constant (--action N every step)")
    parser.add_argument("--task", choices=[task.name for task in tasks], default=tasks[0].name,
                        help=f"--policy other than greedy: the task (default {tasks[0].name})")
    parser.add_argument("--speed", type=finite_float, default=0.0,
                        help="--policy other than greedy: its commanded speed along +x, m/s (default 0)")
    parser.add_argument("--action",
                        help="--policy constant: the action taken every step (a Discrete action's index, or a Box "
                             "action's comma-separated values)")
    parser.add_argument("--episodes", type=int, default=20, help="episodes per policy (default 20)")
    parser.add_argument("--horizon-s", type=finite_float, help="sim seconds per episode at most (default: the task's)")
    parser.add_argument("--backend", choices=("direct", "ros"), default="direct",
                        help="direct: an in-process sim (default); ros: the running sim node")
    parser.add_argument("--seed", type=int, default=0, help="seeds the sim, the random policy and tie breaks")
    parser.add_argument("--initial-tilt", type=finite_float, nargs=2, metavar=("LOW", "HIGH"),
                        help=f"episodes start leaning a random angle in [LOW, HIGH] rad, where the task can (default "
                             f"{EVAL_INITIAL_TILT[0]} {EVAL_INITIAL_TILT[1]}; 0 0: upright)")
    parser.add_argument("--push", type=float, default=0.0, metavar="V",
                        help="kick the base V m/s horizontally in a random direction about every 2 s of sim time, "
                             "drawn from --seed (default 0: no pushes)")
    parser.add_argument("--assist", type=float, default=0.0, metavar="S",
                        help="hold the run's attitude assist at scale S from 0 to 1 (default 0: none)")
    parser.add_argument("--video", type=Path, help="record the first greedy episodes to this .mp4 file")
    parser.add_argument("--video-episodes", type=int, default=3, help="greedy episodes in the video (default 3)")
    parser.add_argument("--video-size", type=video_size, default=(320, 240), help="frame size WxH (default 320x240)")
    parser.add_argument("--slow-motion", type=float, default=1.0, metavar="K",
                        help="the video plays K times slower than real time, K from 1 (default) to 100")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.push) and args.push >= 0.0):
        parser.error(f"--push must be a speed >= 0 (m/s), got {args.push}")
    if not 0.0 <= args.assist <= 1.0:  # NaN too
        parser.error(f"--assist must be a scale from 0 to 1, got {args.assist}")
    if (args.run is None) == (args.policy == "greedy"):
        parser.error("--qtable RUN is needed for the greedy policy, and only for it")
    if args.episodes < 1:
        parser.error("--episodes must be >= 1")
    if args.horizon_s is not None and not 0.0 < args.horizon_s <= MAX_HORIZON_S:
        parser.error(f"--horizon-s must be > 0 and at most {MAX_HORIZON_S:.0f} s, got {args.horizon_s}")
    if not 0 <= args.seed <= MAX_SEED:
        parser.error(f"--seed must be from 0 to {MAX_SEED}, got {args.seed}")
    video = None
    if args.video is not None:
        if args.video.suffix != ".mp4":
            parser.error(f"--video must name an .mp4 file, got {str(args.video)!r}")
        if args.video.is_dir():
            parser.error(f"--video: {str(args.video)!r} is a folder, not an .mp4 file")
        if not args.video.parent.is_dir():
            parser.error(f"--video: the folder {str(args.video.parent)!r} does not exist")
        if not 1 <= args.video_episodes <= args.episodes:
            parser.error(f"--video-episodes must be from 1 to --episodes ({args.episodes}), got {args.video_episodes}")
        if not 1.0 <= args.slow_motion <= 100.0:  # NaN too
            parser.error(f"--slow-motion must be from 1 (real time) to 100, got {args.slow_motion}")
        width, height = args.video_size
        video = VideoRequest(args.video, args.video_episodes, width, height, args.slow_motion)
    if (args.action is None) == (args.policy == "constant"):
        parser.error("--action N is needed for --policy constant, and only for it")
    if args.policy != "greedy":
        if video is not None:
            parser.error("--video records the greedy policy only")
        scripted = constant_policy(args.action) if args.policy == "constant" else policies[args.policy]
        return _main_scripted(parser, args, find_task(list(tasks), args.task), scripted, node_name)
    try:
        run = TrainedRun(args.run, tasks)
    except RunFileError as error:  # a file of the run that is not what its checkpoint recorded (a deep run's model)
        parser.exit(1, f"evaluate.py: {error}\n")
    except (OSError, ParamError, ValueError) as error:
        parser.exit(2, f"evaluate.py: cannot read the trained run {args.run}: {error}\n")
    except ModuleNotFoundError as error:  # a deep run without requirements-deep.txt
        parser.exit(1, f"evaluate.py: {args.run} is a deep agent's run and {error.name} is not installed: "
                       f"./ws setup deep installs requirements-deep.txt\n")
    if over_ros(args.backend):
        try:
            init_ros_node(node_name)
        except SimConnectionError as error:
            parser.exit(1, f"evaluate.py: {error}\n")
    horizon_s = args.horizon_s if args.horizon_s is not None else run.task.eval_horizon_s
    initial_tilt = default_initial_tilt(run.params)
    if args.initial_tilt is not None:
        if initial_tilt is None:
            parser.exit(2, f"evaluate.py: --initial-tilt: the task {run.task.env_id} has no initial tilt\n")
        initial_tilt = (args.initial_tilt[0], args.initial_tilt[1])
    try:
        with_assist(with_initial_tilt(run.params, initial_tilt, "--initial-tilt"), args.assist)
    except ParamError as error:
        parser.exit(2, f"evaluate.py: {error}\n")
    try:
        report = evaluate(run, args.episodes, horizon_s, args.backend, args.seed, video, initial_tilt, args.push,
                          args.assist)
    except (SimConnectionError, SimStateError, RunFileError) as error:
        # SimStateError: the direct backend's non-finite readings; RunFileError: weights that do not fit the model
        parser.exit(1, f"evaluate.py: {error}\n")
    print(json.dumps(report))
    return 0


def _main_scripted(parser: argparse.ArgumentParser, args: argparse.Namespace, task: TaskSpec[Any],
                   scripted: ScriptedPolicy, node_name: str) -> int:
    try:
        params = scripted.env_params(task, task.default_params())
        tilted = hasattr(params, "initial_tilt")
        if args.initial_tilt is not None and not tilted:
            parser.exit(2, f"evaluate.py: --initial-tilt: the task {task.env_id} has no initial tilt\n")
        tilt = (tuple(args.initial_tilt) if args.initial_tilt is not None else EVAL_INITIAL_TILT) if tilted else None
        params = with_assist(with_initial_tilt(params, tilt, "--initial-tilt"), args.assist)
    except ParamError as error:
        parser.exit(2, f"evaluate.py: {error}\n")
    horizon_s = args.horizon_s if args.horizon_s is not None else task.eval_horizon_s
    try:
        if over_ros(args.backend):
            init_ros_node(node_name)
        report = evaluate_scripted(task, args.policy, scripted, params, args.episodes, horizon_s, args.backend,
                                   args.seed, args.speed, args.push, args.assist)
    except (SimConnectionError, SimStateError) as error:
        parser.exit(1, f"evaluate.py: {error}\n")
    except ValueError as error:  # a policy that cannot act in the task (constant's --action, a --speed refused)
        parser.exit(2, f"evaluate.py: {error}\n")
    if args.policy == "constant":
        report["action"] = int(args.action) if args.action.strip().lstrip("-").isdigit() else args.action
    print(json.dumps(report))
    return 0
