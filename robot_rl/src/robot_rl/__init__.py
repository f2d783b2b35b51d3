"""robot_rl: what every task and agent shares, behind this one face.

Tasks (TaskSpec, make_env) and their typed params; the env base (RobotEnv) and the backends that reach the
robot (DirectBackend in-process, RosBackend over ROS); many envs at once (make_vector_env, EnvWorkers, Ray
actors); the agents' registry (AGENTS, find_agent) with tabular Q-learning and Stable-Baselines3's deep
agents; the run folder and its ledger (RunDirectory, RunLedger); evaluation and the training node.

Importing robot_rl imports neither torch, nor ray, nor rospy: the names that need them (the deep agents,
the Ray actors and cluster, the ROS backends, evaluation and the training node) are imported when first
used (`_LAZY`, as gymnasium.wrappers does). Code inside robot_rl imports the defining submodules, never
this face.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .agents.qlearn.qlearn import QLearn
from .agents.qlearn.trainer import QLearningTrainer
from .agents.qlearn.vector_trainer import VectorQLearningTrainer
from .agents.registry import AGENTS, DEFAULT_AGENT, AgentSpec, Trainer, agent_of, checkpoint_of, find_agent
from .atomic import (
    StrPath,
    hold_lock,
    lock_while,
    symlink_atomic,
    write_bytes_atomic,
    write_json_atomic,
    write_text_atomic,
)
from .discretiser import Discretiser
from .envs.backends.base import Backend, Readings, SimStateError, non_finite_problem
from .envs.backends.direct import DirectBackend
from .envs.backends.factory import make_backend
from .envs.base import Placement, RobotEnv, StepOutcome, assist_setter
from .params import (
    MAX_COUNT,
    MAX_SEED,
    ParamError,
    Params,
    Point,
    TaskParams,
    load_yaml_file,
    param,
    parse_scalar,
)
from .policies import ConstantAction, Policy, PolicyMaker, ScriptedPolicy, constant_policy, random_actions
from .runs.ledger import (
    DEFAULT_HOOKS,
    Learner,
    RunLedger,
    TrainingHooks,
    TrainingState,
    format_duration,
    restored_state,
)
from .runs.loaded import LoadedRun
from .runs.plots import MOVING_AVERAGE, moving_average
from .runs.results import (
    DEEP_CHECKPOINT,
    QTABLE_CHECKPOINT,
    EpisodeRecord,
    RunDirectory,
    RunFileError,
    RunLockedError,
    aggregate,
)
from .runs.video import VideoRecorder, frame_every
from .task import (
    TASKS,
    Episode,
    MetricValue,
    RobotSpec,
    StateKey,
    TaskSpec,
    find_task,
    make_env,
    package_path,
    register_tasks,
)
from .workers.base import WorkerError, WorkerRestarted, Workers, as_env_actions, checked_actions, worker_seeds
from .workers.factory import make_env_workers
from .workers.pipe import EnvWorkers
from .workers.private_sim import PrivateSim, default_sigint, free_port, prepare_child, stop_process
from .workers.vector_env import RobotVectorEnv, make_vector_env

if TYPE_CHECKING:
    from . import evaluation, reward_plot, training_node
    from .agents.sb3.params import DqnParams, NetworkParams, PpoParams, SacParams
    from .agents.sb3.policy import DeepPolicy
    from .agents.sb3.trainer import DeepTrainer, EpisodeSchedule, ScaledRewards, build_model
    from .agents.sb3.vec_env import RobotVecEnv, make_vec_env
    from .envs.backends.ros import GazeboStyleBackend, RosBackend, init_ros_node
    from .evaluation import EVAL_INITIAL_TILT, TrainedRun, VideoRequest, default_initial_tilt, evaluate
    from .evaluation import main as evaluation_main
    from .training_node import INTERRUPTED, MAX_ENVS_PER_CORE, NodeParams, run_training_node
    from .workers import cluster
    from .workers.cluster import ClusterError, connect
    from .workers.ray_actors import RayEnvWorkers

# name -> "module" (the name is that module) or "module:attr": what needs torch, ray or rospy, imported when used.
_LAZY: dict[str, str] = {
    # Stable-Baselines3 (torch)
    "NetworkParams": "robot_rl.agents.sb3.params:NetworkParams",
    "DqnParams": "robot_rl.agents.sb3.params:DqnParams",
    "PpoParams": "robot_rl.agents.sb3.params:PpoParams",
    "SacParams": "robot_rl.agents.sb3.params:SacParams",
    "DeepPolicy": "robot_rl.agents.sb3.policy:DeepPolicy",
    "DeepTrainer": "robot_rl.agents.sb3.trainer:DeepTrainer",
    "EpisodeSchedule": "robot_rl.agents.sb3.trainer:EpisodeSchedule",
    "ScaledRewards": "robot_rl.agents.sb3.trainer:ScaledRewards",
    "build_model": "robot_rl.agents.sb3.trainer:build_model",
    "RobotVecEnv": "robot_rl.agents.sb3.vec_env:RobotVecEnv",
    "make_vec_env": "robot_rl.agents.sb3.vec_env:make_vec_env",
    # Ray
    "RayEnvWorkers": "robot_rl.workers.ray_actors:RayEnvWorkers",
    "cluster": "robot_rl.workers.cluster",
    "ClusterError": "robot_rl.workers.cluster:ClusterError",
    "connect": "robot_rl.workers.cluster:connect",
    # rospy
    "RosBackend": "robot_rl.envs.backends.ros:RosBackend",
    "GazeboStyleBackend": "robot_rl.envs.backends.ros:GazeboStyleBackend",
    "init_ros_node": "robot_rl.envs.backends.ros:init_ros_node",
    "evaluation": "robot_rl.evaluation",
    "EVAL_INITIAL_TILT": "robot_rl.evaluation:EVAL_INITIAL_TILT",
    "TrainedRun": "robot_rl.evaluation:TrainedRun",
    "VideoRequest": "robot_rl.evaluation:VideoRequest",
    "default_initial_tilt": "robot_rl.evaluation:default_initial_tilt",
    "evaluate": "robot_rl.evaluation:evaluate",
    "evaluation_main": "robot_rl.evaluation:main",
    "training_node": "robot_rl.training_node",
    "INTERRUPTED": "robot_rl.training_node:INTERRUPTED",
    "MAX_ENVS_PER_CORE": "robot_rl.training_node:MAX_ENVS_PER_CORE",
    "NodeParams": "robot_rl.training_node:NodeParams",
    "run_training_node": "robot_rl.training_node:run_training_node",
    "reward_plot": "robot_rl.reward_plot",
}

__all__ = [
    "AGENTS", "DEEP_CHECKPOINT", "DEFAULT_AGENT", "DEFAULT_HOOKS", "EVAL_INITIAL_TILT", "INTERRUPTED", "MAX_COUNT",
    "MAX_ENVS_PER_CORE", "MAX_SEED", "MOVING_AVERAGE", "QTABLE_CHECKPOINT", "TASKS", "AgentSpec", "Backend",
    "ClusterError", "ConstantAction", "DeepPolicy", "DeepTrainer", "DirectBackend", "Discretiser", "DqnParams",
    "EnvWorkers", "Episode", "EpisodeRecord", "EpisodeSchedule", "GazeboStyleBackend", "Learner", "LoadedRun",
    "MetricValue", "NetworkParams", "NodeParams", "ParamError", "Params", "Placement", "Point", "Policy",
    "PolicyMaker", "PpoParams", "PrivateSim", "QLearn", "QLearningTrainer", "RayEnvWorkers", "Readings", "RobotEnv",
    "RobotSpec", "RobotVecEnv", "RobotVectorEnv", "RosBackend", "RunDirectory", "RunFileError", "RunLedger",
    "RunLockedError", "SacParams", "ScaledRewards", "ScriptedPolicy", "SimStateError", "StateKey", "StepOutcome",
    "StrPath", "TaskParams", "TaskSpec", "TrainedRun", "Trainer", "TrainingHooks", "TrainingState",
    "VectorQLearningTrainer", "VideoRecorder", "VideoRequest", "WorkerError", "WorkerRestarted", "Workers", "agent_of",
    "aggregate", "as_env_actions", "assist_setter", "build_model", "checked_actions", "checkpoint_of", "cluster",
    "connect", "constant_policy", "default_initial_tilt", "default_sigint", "evaluate", "evaluation", "evaluation_main",
    "find_agent", "find_task", "format_duration", "frame_every", "free_port", "init_ros_node", "load_yaml_file",
    "make_backend", "make_env", "make_env_workers", "make_vec_env", "make_vector_env", "moving_average",
    "non_finite_problem", "package_path", "param", "parse_scalar", "prepare_child", "random_actions",
    "register_tasks", "restored_state", "reward_plot", "run_training_node", "stop_process", "symlink_atomic",
    "hold_lock", "lock_while", "training_node", "worker_seeds", "write_bytes_atomic", "write_json_atomic",
    "write_text_atomic",
]


def __getattr__(name: str) -> Any:
    """The lazy names of _LAZY, imported on first use (then kept in the module's namespace)."""
    reference = _LAZY.get(name)
    if reference is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module, _, attr = reference.partition(":")
    value = importlib.import_module(module)
    if attr:
        value = getattr(value, attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
