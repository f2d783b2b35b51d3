"""The body of every training node (the cube's start_training.py, the hopper's start_training_v2.py).

Picks the task (private param ~task, default the package's first), reads and validates its params
from the parameter server (one line naming the key and the file, before anything is written),
makes the env over ROS (or, with ~backend direct, in-process: no sim node, for speed), opens a new run or the
one to resume, trains, and publishes the rewards.
The node's own private params are `NodeParams` (validated as the tasks' are: one line naming the
key), plus ~nepisodes and ~seed, optional overrides of the YAML's. A relative or ~ results_dir is
resolved against ~launch_dir, the folder roslaunch ran in (roslaunch runs nodes in ROS_HOME). Once
trained, video.mp4 next to learning_curve.png shows one greedy episode of the final policy (at most
TRAINING_VIDEO_S of sim time, rendered on the direct backend, so the ROS sim is not needed). ~agent is any
agent of the registry (robot_rl.agents.registry.AGENTS; `find_agent` names them all when one is unknown): the
default qlearn's runs go to <results name>/, every other agent's to <results name>-<agent>/. With ~envs N > 1
the env is N workers, each with a master and a sim of its own (robot_rl.workers; the launch starts no sim then),
or with ~backend direct a World of its own; with ~cluster ("ray" or an address) the workers are Ray actors on
that cluster's nodes (robot_rl.workers.ray_actors), even for one env.

SIGINT or SIGTERM (Ctrl-C, roslaunch shutting down) stops the run cleanly (pybullet_sim.ros.shutdown: a rospy
shutdown, which ends every wait on the sim at once, and a request to stop, never an exception at whatever
line is running): the episode under way is abandoned, a checkpoint and summary.json (marked incomplete)
are written, and the node exits 130. With cluster:=, a wait on a Ray actor (its start, a reply) ends within half a
second of the stop (robot_rl.workers.base.stop_waits_when), and the actors are killed on the way out.
Exit codes: 0 trained, 1 failed (one FATAL line says why), 130 interrupted.
"""
from __future__ import annotations

import dataclasses
import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import rospkg
import rospy
from std_msgs.msg import Float64

from pybullet_sim.ros.client import SimConnectionError
from pybullet_sim.ros.shutdown import shutdown_on_signals, shutting_down

from .agents.registry import DEFAULT_AGENT, AgentSpec, Trainer, find_agent
from .envs.base import assist_setter
from .evaluation import TrainedRun, VideoRequest, evaluate
from .params import ParamError, Params, TaskParams, load_yaml_file, param, parse_scalar
from .runs.curriculum import needs_the_env_in_process
from .runs.ledger import TrainingHooks
from .runs.next_steps import WS_RESULTS_VARIABLE, RunContext, complete_lines, end_block, start_line
from .runs.results import RunDirectory
from .task import TaskSpec, find_task, make_env
from .workers.base import WorkerError, stop_waits_when
from .workers.cluster import ClusterError

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


MAX_ENVS_PER_CORE = 2  # envs:=N beyond this many per core: each env is a sim node and a master, stepped flat out


@dataclass(frozen=True, kw_only=True)
class NodeParams(Params):
    """The training node's private params (~name), from the launch file's arguments."""

    task: str = param(default="", doc="the task to train; empty: the package's first")
    config_file: str = param(default="rosparam", doc="the task's YAML (named in errors)")
    default_config: str = param(default="", doc="the robot's YAML when none is given (main.launch's)")
    results_dir: str = param(default="", doc="where runs go; empty: $ROS_HOME/training_results")
    launch_dir: str = param(default="", doc="the folder roslaunch ran in: a relative results_dir is under it")
    run: str = param(default="", doc="the run's name; empty: the UTC time (new) or latest (resume)")
    resume: bool = param(default=False, doc="continue the run from its checkpoint")
    timeout: float = param(low=0.0, low_open=True, high=3600.0, default=10.0, doc="s, every wait on the sim")
    quiet: bool = param(default=False, doc="the EP: lines and the tutorial's closing lines at debug level")
    video: bool = param(default=True, doc="video.mp4 of the greedy policy once trained")
    agent: str = param(default=DEFAULT_AGENT, doc="a name in robot_rl.agents")
    agent_config: str = param(default="", doc="a deep agent's YAML; empty: the task package's "
                                              "config/agents/<task>.<agent>.yaml, else robot_rl/config/<agent>.yaml")
    max_steps: int = param(low=0, high=10**12, default=0, doc="a deep agent's env step budget; 0: nepisodes decides")
    envs: int = param(low=1, default=1, doc="envs; more than 1: workers with a master and a sim each")
    cluster: str = param(default="", doc="empty: the workers on this machine; ray or HOST:PORT: Ray actors there")
    backend: str = param(choices=("ros", "direct"), default="ros",
                         doc="ros: the env steps the launch's sim node in lockstep; direct: an in-process World "
                             "(no sim node; the workers' too)")

    def check(self, source: str) -> None:
        cores = os.cpu_count() or 1
        if not self.cluster and self.envs > MAX_ENVS_PER_CORE * cores:  # a cluster's CPUs are Ray's to count
            raise ParamError(f"{source}: parameter 'envs' = {self.envs} is more than {MAX_ENVS_PER_CORE} per core "
                             f"({MAX_ENVS_PER_CORE * cores} on this machine's {cores}): each env steps a sim node "
                             f"of its own as fast as it can, and more would only slow every one down")

    @property
    def results_root(self) -> Path:
        """results_dir with ~ expanded, and a relative one under launch_dir (roslaunch runs nodes in ROS_HOME)."""
        if not self.results_dir:
            return Path(rospkg.get_ros_home()) / "training_results"
        path = Path(self.results_dir).expanduser()
        return path if path.is_absolute() else Path(self.launch_dir or os.getcwd()) / path


NUMBERS = ("max_steps", "envs", "nepisodes", "seed", "timeout")  # private params the launch files pass as text


def _private(names: Sequence[str]) -> dict[str, Any]:
    """The node's private params that are set; numbers given as text (the launch files pass them with type="str",
    as a value beyond XML-RPC's 32-bit ints would stop roslaunch with a traceback) read as YAML reads them."""
    values = {name: rospy.get_param(f"~{name}") for name in names if rospy.has_param(f"~{name}")}
    return {name: parse_scalar(value) if isinstance(value, str) and name in NUMBERS else value
            for name, value in values.items()}


def _read_node_params() -> NodeParams:
    return NodeParams.from_mapping(_private([f.name for f in dataclasses.fields(NodeParams)]), rospy.get_name())


def _read_params(task: TaskSpec[Any], node: NodeParams) -> TaskParams:
    config_file = node.config_file
    if Path(config_file).is_file():  # rosparam keeps the last of two equal keys and every unknown one: refused here
        task.params_from_document(load_yaml_file(config_file), config_file, strict=True)
    namespace = task.params_namespace
    params = task.params_type.from_mapping(rospy.get_param(namespace, {}), f"{config_file} ({namespace.rstrip('/')}/)")
    overrides = _private(("nepisodes", "seed"))
    return params.with_changes(rospy.get_name(), **overrides) if overrides else params


def _given_launch_args(node: NodeParams) -> tuple[str, ...]:
    """The launch arguments this run was started with, other than their defaults, that training it further needs
    again: its config, agent_config, backend, envs, cluster and results_dir (as given; not ./ws run's default)."""
    given = []
    if Path(node.config_file).is_file() and not (
            node.default_config and Path(node.config_file).resolve() == Path(node.default_config).resolve()):
        given.append(f"config:={node.config_file}")
    defaults = {field.name: field.default for field in dataclasses.fields(NodeParams)}
    given += [f"{name}:={getattr(node, name)}" for name in ("agent_config", "backend", "envs", "cluster")
              if getattr(node, name) != defaults[name]]
    if node.results_dir and node.results_dir != os.environ.get(WS_RESULTS_VARIABLE):
        given.append(f"results_dir:={node.results_dir}")
    return tuple(given)


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
    metrics = ", ".join(f"{name.removesuffix('_rate').removeprefix('mean_')} {value:.3g}"
                        for name, value in report["greedy"].items() if value is not None)
    # The video's one episode stops at TRAINING_VIDEO_S, evaluate.py's episodes at the task's horizon (the cube's
    # 60 s): a success that comes later is not in the video's figures. Say so where they are printed.
    cut = f"cut at {report['horizon_s']:.0f} s of sim time, where evaluate.py runs {task.eval_horizon_s:.0f} s" \
        if report["horizon_s"] < task.eval_horizon_s else f"at most {report['horizon_s']:.0f} s of sim time"
    rospy.loginfo("Video of the greedy policy: %s (%d frames at %.1f frames/s, made in %.1f s): one episode, %s; in "
                  "it: %s", run.video_mp4, report["video"]["frames"], report["video"]["fps"],
                  time.monotonic() - start, cut, metrics)


def _read_agent(node: NodeParams, task: TaskSpec[Any]) -> tuple[AgentSpec, Params | None, Path | None]:
    """The agent, its own params (None: it has none) and their file: ~agent_config, else the task's own."""
    try:
        agent = find_agent(node.agent)
    except ParamError as error:
        raise ParamError(f"{rospy.get_name()}: parameter '~agent': {error}") from None
    config = Path(node.agent_config).resolve() if node.agent_config else agent.config_for(task)
    try:
        agent_params = agent.load_params(config)
    except ModuleNotFoundError as error:
        raise ParamError(f"agent {agent.name} needs {error.name}, which is not installed: ./ws run ... "
                         f"agent:={agent.name} installs requirements-deep.txt (or ./ws setup deep)") from None
    return agent, agent_params, config


def _open_run(node: NodeParams, results_name: str, checkpoint_name: str, params: TaskParams,
              task: TaskSpec[Any]) -> RunDirectory:
    """The run to train: a new one (named `node.run`, or by the time), or the one to resume (`node.run`, or latest)."""
    root = node.results_root.resolve()
    if node.resume:
        return RunDirectory.named(root, results_name, node.run, checkpoint_name) if node.run else \
            RunDirectory.latest(root, results_name, checkpoint_name)
    try:
        return RunDirectory.create(root, results_name, params.to_mapping(), task.metric_names,
                                   run_name=node.run or None, checkpoint_name=checkpoint_name)
    except FileExistsError:
        raise FileExistsError(f"a run {root / results_name / node.run} exists already: resume:=true run:={node.run} "
                              f"continues it; a new run needs another name") from None


def _completed_summary(run: RunDirectory, nepisodes: int, max_steps: int) -> dict[str, Any] | None:
    """The run's summary.json if it says the run is complete for this nepisodes (the run's budget: the task's, or
    the agent's params' count) or max_steps, else None."""
    try:
        summary = json.loads(run.summary_json.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(summary, dict) or not summary.get("completed"):
        return None
    episodes, steps = summary.get("episodes", 0), summary.get("env_steps", 0)
    return summary if episodes >= nepisodes or (max_steps and steps >= max_steps) else None


def _make_env(task: TaskSpec[Any], params: TaskParams, agent: AgentSpec, envs: int, timeout: float,
              cluster: str, backend: str = "ros") -> Any:
    """The env(s) to train on: over this master's sim, or N workers (or Ray actors) with sims of their own; with
    backend direct, an in-process World (seeded with the run's seed), or N workers with one each."""
    direct = backend == "direct"
    if envs == 1 and not cluster and not agent.own_envs:
        if direct:
            rospy.loginfo("Training in-process (backend direct): the env steps a World of its own, no sim node")
            return make_env(task, params=params, backend="direct", seed=params.seed)
        return make_env(task, params=params, backend="ros", ros_timeout=timeout)
    where = f" as Ray actors on cluster {cluster}" if cluster else ""
    rospy.loginfo("Starting %d envs%s, each with %s", envs, where,
                  "an in-process World (backend direct)" if direct else "a ROS master and a sim node of its own")
    env = agent.make_vector_env(task, envs, backend=backend, seed=params.seed, params=params, ros_timeout=timeout,
                                cluster=cluster or None)
    for i, info in enumerate(env.workers.worker_info if cluster else []):
        rospy.loginfo("Env %d/%d: a Ray actor on node %s (%s), its master %s", i + 1, envs, info["node_ip"],
                      info["node_id"], info["master_uri"])
    return env


def run_training_node(tasks: Sequence[TaskSpec[Any]], node_name: str) -> int:
    rospy.init_node(node_name, anonymous=True, log_level=rospy.INFO, disable_signals=True)
    signals = shutdown_on_signals()  # turns Ctrl-C into a stop request

    def should_stop() -> bool:
        return bool(signals) or shutting_down()
    stop_waits_when(should_stop)  # a wait on Ray actors ends within half a second of a stop (WorkersStopped)
    try:
        node = _read_node_params()
        task = find_task(list(tasks), node.task or tasks[0].name)
        params = _read_params(task, node)
        agent, agent_params, agent_config = _read_agent(node, task)
    except ParamError as error:
        return _fail(str(error))
    results_root = node.results_root
    log_episode = rospy.logdebug if node.quiet else rospy.loginfo
    own_episodes = agent.own_episodes(agent_params)  # bc_dagger's: its params count them, not nepisodes
    nepisodes = params.nepisodes if own_episodes is None else own_episodes
    context = RunContext(package=task.package, task=task.name, several_tasks=len(tasks) > 1, agent=node.agent,
                         default_agent=DEFAULT_AGENT, run_path=Path(), launch_dir=node.launch_dir,
                         own_episodes=own_episodes is not None, given=_given_launch_args(node))
    try:
        env = _make_env(task, params, agent, node.envs, node.timeout, node.cluster, node.backend)
    except (SimConnectionError, WorkerError, OSError, ClusterError) as error:  # OSError: e.g. a master refusing
        if should_stop():  # e.g. the sim failed to start and roslaunch is ending the launch
            if isinstance(error, WorkerError):
                error.discard_logs()  # the stop's doing, not a fault to look into
            rospy.logwarn("stopped before training started")
            return INTERRUPTED
        return _fail(str(error))
    except ModuleNotFoundError as error:  # cluster:= without requirements-distributed.txt
        return _fail(f"cluster:={node.cluster} needs {error.name}, which is not installed: ./ws setup distributed")
    except ValueError as error:  # params the env refuses (e.g. a running_step of more physics steps than a step takes)
        return _fail(f"{node.config_file}: {error}")
    try:  # before the run folder: an agent that cannot train this task (or whose buffer cannot fit) writes nothing
        agent.check_fit(env, agent_params, f"agent {agent.name} on {task.env_id}")
        if params.attitude_assist.adapt_every and assist_setter(env) is None:
            raise ParamError(f"{node.config_file}: {needs_the_env_in_process(params.attitude_assist)}")
        if params.selection.every and (not agent.table_checks or node.envs > 1):
            raise ParamError(f"{node.config_file}: parameter 'selection/every' ({params.selection.every}) checks the "
                             "Q-table during training: agent:=qlearn with envs:=1 only (this run: "
                             f"agent:={agent.name}, envs:={node.envs}); set it to 0")
    except ParamError as error:
        _close_quietly(env)
        return _fail(str(error))
    results_name, checkpoint_name = agent.results_name(task), agent.checkpoint_name
    run: RunDirectory | None = None
    trainer: Trainer | None = None

    def episodes_saved() -> int:
        return trainer.state.episode if trainer is not None else 0
    try:
        run = _open_run(node, results_name, checkpoint_name, params, task)
        context = dataclasses.replace(context, run_path=run.path)
        rospy.loginfo(start_line(dataclasses.replace(context, launch_dir=""), task.env_id, nepisodes,
                                 node.max_steps, None, node.quiet))
        if agent_config is not None:
            rospy.loginfo("Agent %s's params: %s", agent.name, agent_config)
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
        trainer = agent.make_trainer(env, task, params, run, hooks, resume=node.resume, agent_params=agent_params,
                                     max_steps=node.max_steps or None, agent_config=agent_config)
        # after the trainer has checked the checkpoint: a damaged one is refused, never called complete
        complete = _completed_summary(run, nepisodes, node.max_steps) if node.resume else None
        if complete is not None:
            for line in complete_lines(context, complete):
                rospy.logwarn(line)
            return 0
        summary = trainer.train()
    except (FileNotFoundError, FileExistsError, ValueError) as error:
        return _fail(str(error))
    except (WorkerError, SimConnectionError, OSError) as error:
        if should_stop():  # the error is the stop's (e.g. the launch's master gone: connection refused)
            if run is None:
                rospy.logwarn("stopped before training started: %s", error)
                return INTERRUPTED
            return _interrupted(episodes_saved(), run)
        if isinstance(error, OSError) and not isinstance(error, ConnectionError):  # the results: read-only, full...
            return _fail(f"cannot write the results: {error.filename or results_root}: {error.strerror or error}")
        saved = f" Episodes up to episode {episodes_saved()} are saved in {run.path}; continue with resume:=true" \
            if run is not None else ""
        return _fail(f"training stopped: {error}.{saved}")
    finally:
        _close_quietly(env)
    if not summary["completed"]:
        return _interrupted(summary["episodes"], run)
    rospy.loginfo("Training complete: %d episodes, %d env steps in %.1f s (%.0f steps/s). Results: %s",
                  summary["episodes"], summary["env_steps"], summary["wall_time_s"], summary["env_steps_per_s"] or 0.0,
                  run.path)
    if node.video:
        try:
            _write_video(tasks, task, run, params.seed)
        except (OSError, ValueError, RuntimeError) as error:
            return _fail(f"the run is saved in {run.path}, but its video could not be written: {error}")
    for line in end_block(context, summary, run.video_mp4 if node.video else None):
        rospy.loginfo(line)
    return 0
