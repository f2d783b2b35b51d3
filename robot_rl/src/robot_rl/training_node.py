"""The body of both training nodes (the cube's start_training.py, the hopper's start_training_v2.py).

Reads and validates the robot's params (one line naming the key and the file, before anything is
written), makes the env over ROS, opens a new run or the latest one to resume, trains, and publishes
the rewards. Private params: ~config_file (named in errors), ~results_dir (default
<repo>/training_results), ~resume, ~nepisodes (optional override), ~timeout (s, every wait on the sim).
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Dict

import gymnasium
import rospy
from std_msgs.msg import Float64

from pybullet_sim.client import SimConnectionError
from .params import ParamError
from .results import RunDirectory
from .training import QLearningTrainer, make_trainer_config

REPO = Path(__file__).resolve().parents[3]


@dataclass(frozen=True)
class TrainingNodeSpec:
    robot: str                                   # results go to <results_dir>/<robot>/
    env_id: str
    params_namespace: str                        # "/moving_cube" or "/" (the hopper's root namespace)
    validate_params: Callable[[Dict[str, Any], str], Dict[str, Any]]
    make_state_key: Callable[[Dict[str, Any]], Any]
    reward_topic: str
    episode_reward_topic: str
    publish_cumulated_reward: bool               # the hopper tutorial publishes the running sum each step


def _read_params(spec: TrainingNodeSpec) -> Dict[str, Any]:
    config_file = rospy.get_param("~config_file", "rosparam")
    params = spec.validate_params(rospy.get_param(spec.params_namespace, {}),
                                  f"{config_file} ({spec.params_namespace.rstrip('/')}/)")
    nepisodes = rospy.get_param("~nepisodes", params["nepisodes"])
    if isinstance(nepisodes, bool) or not isinstance(nepisodes, int) or nepisodes < 1:
        raise ParamError(f"{rospy.get_name()}/nepisodes: expected an int >= 1, got {nepisodes!r}")
    params["nepisodes"] = nepisodes
    return params


def run_training_node(spec: TrainingNodeSpec, node_name: str) -> int:
    rospy.init_node(node_name, anonymous=True, log_level=rospy.INFO)
    try:
        params = _read_params(spec)
    except ParamError as error:
        rospy.logfatal(str(error))
        print(error, file=sys.stderr, flush=True)
        return 1
    results_root = Path(rospy.get_param("~results_dir", str(REPO / "training_results"))).resolve()
    resume = rospy.get_param("~resume", False)
    timeout = float(rospy.get_param("~timeout", 10.0))
    try:
        env = gymnasium.make(spec.env_id, backend="ros", params=params, ros_timeout=timeout)
        run = RunDirectory.latest(results_root, spec.robot) if resume else \
            RunDirectory.create(results_root, spec.robot, params)
    except (SimConnectionError, FileNotFoundError) as error:
        rospy.logfatal(str(error))
        return 1
    rospy.loginfo("Results go to %s", run.path)
    reward_pub = rospy.Publisher(spec.reward_topic, Float64, queue_size=10)
    episode_reward_pub = rospy.Publisher(spec.episode_reward_topic, Float64, queue_size=10)

    def on_step(reward: float, cumulated: float) -> None:
        reward_pub.publish(Float64(cumulated if spec.publish_cumulated_reward else reward))

    try:
        trainer = QLearningTrainer(env, spec.make_state_key(params), make_trainer_config(params), run,
                                   log=rospy.loginfo, on_step=on_step,
                                   on_episode=lambda cumulated: episode_reward_pub.publish(Float64(cumulated)),
                                   should_stop=rospy.is_shutdown, resume=resume)
    except (FileNotFoundError, ValueError) as error:
        rospy.logfatal(str(error))
        env.close()
        return 1
    try:
        summary = trainer.train()
    except SimConnectionError as error:
        rospy.logfatal("training stopped: %s. Episodes up to the last checkpoint are in %s; continue with "
                       "resume:=true", error, run.path)
        return 1
    finally:
        env.close()
    rospy.loginfo("Training %s: %d episodes, %d env steps in %.1f s (%.0f steps/s). Results: %s",
                  "complete" if summary["completed"] else "stopped", summary["episodes"], summary["env_steps"],
                  summary["wall_time_s"], summary["env_steps_per_s"] or 0.0, run.path)
    return 0
