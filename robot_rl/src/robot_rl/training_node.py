"""The body of every training node (the cube's start_training.py, the hopper's start_training_v2.py).

Picks the task (private param ~task, default the package's first), reads and validates its params
from the parameter server (one line naming the key and the file, before anything is written),
makes the env over ROS, opens a new run or the latest one to resume, trains, and publishes the
rewards. Private params: ~task, ~config_file (named in errors), ~results_dir (default
$ROS_HOME/training_results), ~resume, ~nepisodes and ~seed (optional overrides of the YAML's),
~timeout (s, every wait on the sim), ~quiet (the per-episode "EP:" lines go to the debug log
level), ~video (default true: once trained, video.mp4 next to learning_curve.png shows one greedy
episode of the final policy, at most TRAINING_VIDEO_S of sim time, rendered on the direct backend so
that the ROS sim is not needed),
~agent (a name in robot_rl.agents: qlearn, the tutorials' tabular Q-learning; dqn or ppo,
Stable-Baselines3's, their runs going to <results name>-<agent>/), ~agent_config (a deep agent's YAML,
default robot_rl/config/<agent>.yaml), ~max_steps (a deep agent's env step budget; 0: nepisodes decides),
~envs (1: the env over this master's sim; N > 1: N workers, each with a master and a sim of its own,
see robot_rl.vector; the launch's own sim then idles).

SIGINT or SIGTERM (Ctrl-C, roslaunch shutting down) stops the run cleanly (pybullet_sim.shutdown: a rospy
shutdown, which ends every wait on the sim at once, and a request to stop, never an exception at whatever
line is running): the episode under way is abandoned, a checkpoint and summary.json (marked incomplete)
are written, and the node exits 130.
Exit codes: 0 trained, 1 failed (one FATAL line says why), 130 interrupted.
"""
from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import rospkg
import rospy
from std_msgs.msg import Float64

from pybullet_sim.client import SimConnectionError
from pybullet_sim.shutdown import shutdown_on_signals, shutting_down

from .agents import DEFAULT_AGENT, AgentSpec, find_agent
from .evaluation import TrainedRun, VideoRequest, evaluate
from .ledger import TrainingHooks
from .params import ParamError, Params, TaskParams, load_yaml_file
from .results import RunDirectory
from .task import TaskSpec, find_task, make_env
from .vector import WorkerError

INTERRUPTED = 130  # the shell's code for a command ended by SIGINT
TRAINING_VIDEO_S = 10.0  # sim seconds at most in a training run's video


def _fail(message: str) -> int:
    rospy.logfatal(message)
    return 1


def _interrupted(episodes: int, run: RunDirectory) -> int:
    message = (f"training interrupted after episode {episodes}: checkpoint and summary.json (incomplete) in "
               f"{run.path}; continue with resume:=true")
    rospy.logwarn(message)
    return INTERRUPTED


def _read_params(task: TaskSpec[Any]) -> TaskParams:
    config_file = rospy.get_param("~config_file", "rosparam")
    if Path(config_file).is_file():
        load_yaml_file(config_file)  # rosparam keeps the last of two equal keys; a strict loader refuses them
    namespace = task.params_namespace
    params = task.params_type.from_mapping(rospy.get_param(namespace, {}), f"{config_file} ({namespace.rstrip('/')}/)")
    overrides = {key: rospy.get_param(f"~{key}") for key in ("nepisodes", "seed") if rospy.has_param(f"~{key}")}
    return params.with_changes(rospy.get_name(), **overrides) if overrides else params


def _close_quietly(env: Any) -> None:
    """Close the env; after a shutdown its connections may already be gone, which is fine."""
    try:
        env.close()
    except (SimConnectionError, rospy.ROSException, OSError):  # OSError: the master is gone
        pass


def _write_video(tasks: Sequence[TaskSpec[Any]], task: TaskSpec[Any], run: RunDirectory, seed: int) -> None:
    """video.mp4: one greedy episode of the run's final Q-table, as evaluate.py --video records it."""
    start = time.monotonic()
    partial = run.path / "video.partial.mp4"  # renamed when complete: video.mp4 is whole or absent
    report = evaluate(TrainedRun(run.path, tasks), episodes=1, horizon_s=min(task.eval_horizon_s, TRAINING_VIDEO_S),
                      backend="direct", seed=seed, video=VideoRequest(partial, episodes=1))
    os.replace(partial, run.video_mp4)
    metrics = ", ".join(f"{name} {value:.3g}" for name, value in report["greedy"].items() if value is not None)
    rospy.loginfo("Video of the greedy policy: %s (%d frames at %.1f frames/s: one episode of at most %.1f s of sim "
                  "time, made in %.1f s; %s)", run.video_mp4, report["video"]["frames"], report["video"]["fps"],
                  report["horizon_s"], time.monotonic() - start, metrics)


def _read_agent() -> tuple[AgentSpec, Params | None, int, int | None]:
    """(agent, its own params or None, envs, max_steps or None) from the private params."""
    name, envs, max_steps = rospy.get_param("~agent", DEFAULT_AGENT), rospy.get_param("~envs", 1), \
        rospy.get_param("~max_steps", 0)
    if not (isinstance(envs, int) and not isinstance(envs, bool) and envs >= 1):
        raise ParamError(f"{rospy.get_name()}: parameter '~envs' must be a whole number >= 1, got {envs!r}")
    if not (isinstance(max_steps, int) and not isinstance(max_steps, bool) and max_steps >= 0):
        raise ParamError(f"{rospy.get_name()}: parameter '~max_steps' must be a whole number >= 0, got {max_steps!r}")
    try:
        agent = find_agent(name)
    except ParamError as error:
        raise ParamError(f"{rospy.get_name()}: parameter '~agent': {error}") from None
    config = rospy.get_param("~agent_config", "")
    try:
        agent_params = agent.load_params(Path(config) if config else None)
    except ModuleNotFoundError as error:
        raise ParamError(f"agent {name} needs {error.name}, which is not installed: ./ws run ... agent:={name} "
                         f"installs requirements-deep.txt (or ./ws setup deep)") from None
    return agent, agent_params, envs, max_steps or None


def _make_env(task: TaskSpec[Any], params: TaskParams, agent: AgentSpec, envs: int, timeout: float) -> Any:
    """The env(s) to train on: over this master's sim, or N workers with sims of their own."""
    if envs == 1:
        return make_env(task, params=params, backend="ros", ros_timeout=timeout)
    rospy.loginfo("Starting %d envs, each with a ROS master and a sim node of its own", envs)
    return agent.make_vector_env(task, envs, backend="ros", seed=params.seed, params=params, ros_timeout=timeout)


def run_training_node(tasks: Sequence[TaskSpec[Any]], node_name: str) -> int:
    rospy.init_node(node_name, anonymous=True, log_level=rospy.INFO, disable_signals=True)
    signals = shutdown_on_signals()  # turns Ctrl-C into a stop request

    def should_stop() -> bool:
        return bool(signals) or shutting_down()
    try:
        task = find_task(list(tasks), rospy.get_param("~task", tasks[0].name))
        params = _read_params(task)
        agent, agent_params, envs, max_steps = _read_agent()
    except ParamError as error:
        return _fail(str(error))
    results_root = Path(rospy.get_param("~results_dir", str(Path(rospkg.get_ros_home()) / "training_results")))
    resume = rospy.get_param("~resume", False)
    timeout = float(rospy.get_param("~timeout", 10.0))
    log_episode = rospy.logdebug if rospy.get_param("~quiet", False) else rospy.loginfo
    video = rospy.get_param("~video", True)  # read now: nothing needs the master once training runs
    try:
        env = _make_env(task, params, agent, envs, timeout)
    except (SimConnectionError, WorkerError) as error:
        if should_stop():  # e.g. the sim failed to start and roslaunch is ending the launch
            rospy.logwarn("stopped before training started: %s", error)
            return INTERRUPTED
        return _fail(str(error))
    results_name, checkpoint_name = agent.results_name(task), agent.checkpoint_name
    try:
        run = RunDirectory.latest(results_root, results_name, checkpoint_name) if resume else \
            RunDirectory.create(results_root.resolve(), results_name, params.to_mapping(), task.metric_names,
                                checkpoint_name=checkpoint_name)
        rospy.loginfo("Results go to %s", run.path)
        reward_pub = rospy.Publisher(task.reward_topic, Float64, queue_size=10)
        episode_reward_pub = rospy.Publisher(task.episode_reward_topic, Float64, queue_size=10)

        def publish(publisher: rospy.Publisher, value: float) -> None:
            try:
                publisher.publish(Float64(value))
            except rospy.ROSException:  # publish() to a topic the shutdown closed: the run stops at the next step
                if not should_stop():
                    raise

        def on_step(reward: float, cumulated: float) -> None:
            publish(reward_pub, cumulated if task.publish_cumulated_reward else reward)

        def on_episode(cumulated: float) -> None:
            publish(episode_reward_pub, cumulated)
        hooks = TrainingHooks(log=rospy.loginfo, log_episode=log_episode, on_step=on_step, on_episode=on_episode,
                              should_stop=should_stop)
        trainer = agent.make_trainer(env, task, params, run, hooks, resume=resume, agent_params=agent_params,
                                     max_steps=max_steps)
        summary = trainer.train()
    except (FileNotFoundError, ValueError) as error:
        return _fail(str(error))
    except (WorkerError, SimConnectionError) as error:
        if should_stop():
            return _interrupted(trainer.state.episode, run)
        return _fail(f"training stopped: {error}. Episodes up to episode {trainer.state.episode} are saved in "
                     f"{run.path}; continue with resume:=true")
    except OSError as error:  # the results folder: read-only, disk full...
        return _fail(f"cannot write the results: {error.filename or results_root}: {error.strerror or error}")
    finally:
        _close_quietly(env)
    if not summary["completed"]:
        return _interrupted(summary["episodes"], run)
    rospy.loginfo("Training complete: %d episodes, %d env steps in %.1f s (%.0f steps/s). Results: %s",
                  summary["episodes"], summary["env_steps"], summary["wall_time_s"], summary["env_steps_per_s"] or 0.0,
                  run.path)
    if video:
        try:
            _write_video(tasks, task, run, params.seed)
        except (OSError, ValueError, RuntimeError) as error:
            return _fail(f"the run is saved in {run.path}, but its video could not be written: {error}")
    return 0
