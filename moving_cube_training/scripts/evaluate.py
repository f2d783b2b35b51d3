#!/usr/bin/env python3
"""Evaluate a trained cube Q-table against a random policy; the last output line is one JSON object.

  rosrun moving_cube_training evaluate.py --qtable PATH --episodes N [--backend ros|direct] [--seed S]

PATH is a run's qtable.json (or the run folder). The run's params.yaml gives the task parameters.
Over ROS a cube sim must be running (e.g. ./ws exec roslaunch launch/cube_sim.launch). Success means
the episode ended at least 0.5 m further along +y than it started.
"""
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from moving_cube_training.one_disk_walk import MovingCubeOneDiskWalkEnv
from moving_cube_training.params import validate_params
from moving_cube_training.state import CubeStateKey
from robot_rl.evaluation import greedy_and_random, load_trained_run

SUCCESS_DISTANCE = 0.5  # m along +y


def run_episodes(env, policy, episodes: int) -> dict:
    returns, distances = [], []
    for _ in range(episodes):
        observation, _ = env.reset()
        total, info = 0.0, {"y_travelled": 0.0}
        while True:
            observation, reward, terminated, truncated, info = env.step(policy(observation))
            total += reward
            if terminated or truncated:
                break
        returns.append(total)
        distances.append(info["y_travelled"])
    return {"mean_return": float(np.mean(returns)), "mean_y_distance": float(np.mean(distances)),
            "success_rate": float(np.mean([d >= SUCCESS_DISTANCE for d in distances]))}


def main(argv) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--qtable", required=True, type=Path, help="a run's qtable.json or run folder")
    parser.add_argument("--episodes", required=True, type=int)
    parser.add_argument("--backend", choices=("ros", "direct"), default="ros")
    parser.add_argument("--seed", type=int, default=0, help="seeds the random policy, tie breaks and the direct sim")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error("--episodes must be >= 1")
    try:
        qlearn, params = load_trained_run(args.qtable, validate_params)
    except (OSError, KeyError, ValueError) as error:
        parser.error(f"cannot read the trained Q-table {args.qtable}: {error}")
    if args.backend == "ros":
        import rospy
        rospy.init_node("evaluate_moving_cube", anonymous=True)
    env = MovingCubeOneDiskWalkEnv(backend=args.backend, params=params, seed=args.seed)
    greedy, random_policy = greedy_and_random(env, CubeStateKey(params).key, qlearn, args.episodes, args.seed,
                                              run_episodes)
    print(json.dumps({"episodes": args.episodes, "greedy": greedy, "random": random_policy}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
