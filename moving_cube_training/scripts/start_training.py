#!/usr/bin/env python3
"""Train the moving cube with Q-learning (the tutorial's start_training.py), over ROS in lockstep.

Params: /moving_cube/* (config/moving_cube_qlearn.yaml, loaded by launch/main.launch), validated
before anything is written. Private params: ~config_file (named in errors), ~results_dir
(default <repo>/training_results), ~resume (continue the latest run from its checkpoint),
~nepisodes (optional override of /moving_cube/nepisodes), ~timeout (s, for every wait on the sim).
Publishes /moving_cube/reward (each step's reward) and /moving_cube/episode_reward (each episode's).
"""
import sys
from pathlib import Path

import gymnasium
import rospy
from std_msgs.msg import Float64

import moving_cube_training
from moving_cube_training.params import NAMESPACE, validate_params
from moving_cube_training.state import CubeStateKey
from pybullet_sim.client import SimConnectionError
from robot_rl.params import ParamError
from robot_rl.results import RunDirectory
from robot_rl.training import QLearningTrainer, make_trainer_config

REPO = Path(__file__).resolve().parents[2]


def main() -> int:
    rospy.init_node("movingcube_gym", anonymous=True, log_level=rospy.INFO)
    config_file = rospy.get_param("~config_file", "rosparam")
    try:
        params = validate_params(rospy.get_param(f"/{NAMESPACE}", {}), f"{config_file} (/{NAMESPACE}/)")
        nepisodes = rospy.get_param("~nepisodes", params["nepisodes"])
        if isinstance(nepisodes, bool) or not isinstance(nepisodes, int) or nepisodes < 1:
            raise ParamError(f"~nepisodes: expected an int >= 1, got {nepisodes!r}")
        params["nepisodes"] = nepisodes
    except ParamError as error:
        rospy.logfatal(str(error))
        print(error, file=sys.stderr, flush=True)
        return 1
    results_root = Path(rospy.get_param("~results_dir", str(REPO / "training_results"))).resolve()
    resume = rospy.get_param("~resume", False)
    timeout = float(rospy.get_param("~timeout", 10.0))

    try:
        env = gymnasium.make(moving_cube_training.ENV_ID, backend="ros", params=params, ros_timeout=timeout)
        run = RunDirectory.latest(results_root, "moving_cube") if resume else \
            RunDirectory.create(results_root, "moving_cube", params)
    except (SimConnectionError, FileNotFoundError) as error:
        rospy.logfatal(str(error))
        return 1
    rospy.loginfo("Results go to %s", run.path)
    reward_pub = rospy.Publisher("/moving_cube/reward", Float64, queue_size=10)
    episode_reward_pub = rospy.Publisher("/moving_cube/episode_reward", Float64, queue_size=10)
    trainer = QLearningTrainer(env, CubeStateKey(params), make_trainer_config(params), run, log=rospy.loginfo,
                               on_step=lambda reward, _cumulated: reward_pub.publish(Float64(reward)),
                               on_episode=lambda cumulated: episode_reward_pub.publish(Float64(cumulated)),
                               should_stop=rospy.is_shutdown, resume=resume)
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


if __name__ == "__main__":
    sys.exit(main())
