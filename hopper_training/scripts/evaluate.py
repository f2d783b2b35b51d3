#!/usr/bin/env python3
"""Evaluate a trained monoped Q-table against a random policy; the last output line is one JSON object.

  rosrun hopper_training evaluate.py --qtable PATH --episodes N [--horizon STEPS] [--backend ros|direct] [--seed S]

PATH is a run's qtable.json (or the run folder); the run's params.yaml gives the task parameters.
Each episode runs until the monoped falls or `--horizon` env steps (default 3000 = 3 s of sim time:
long enough that random actions make it fall in most episodes; the training's nsteps is only 1000).
Over ROS a hopper sim must be running (./ws exec roslaunch launch/hopper_sim.launch).
"""
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from hopper_training.monoped_env import MonopedEnv
from hopper_training.params import validate_params
from robot_rl.evaluation import greedy_and_random, load_trained_run


def run_episodes(env, policy, episodes: int) -> dict:
    returns, lengths, falls = [], [], []
    for _ in range(episodes):
        observation, _ = env.reset()
        total, steps = 0.0, 0
        while True:
            observation, reward, terminated, truncated, _ = env.step(policy(observation))
            total += reward
            steps += 1
            if terminated or truncated:
                break
        returns.append(total)
        lengths.append(steps)
        falls.append(terminated)
    return {"mean_return": float(np.mean(returns)), "mean_episode_steps": float(np.mean(lengths)),
            "fall_rate": float(np.mean(falls))}


def main(argv) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--qtable", required=True, type=Path, help="a run's qtable.json or run folder")
    parser.add_argument("--episodes", required=True, type=int)
    parser.add_argument("--horizon", type=int, default=3000, help="env steps per episode at most")
    parser.add_argument("--backend", choices=("ros", "direct"), default="ros")
    parser.add_argument("--seed", type=int, default=0, help="seeds the random policy, tie breaks and the direct sim")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.horizon < 1:
        parser.error("--episodes and --horizon must be >= 1")
    try:
        qlearn, params = load_trained_run(args.qtable, validate_params)
    except (OSError, KeyError, ValueError) as error:
        parser.error(f"cannot read the trained Q-table {args.qtable}: {error}")
    params["nsteps"] = args.horizon
    if args.backend == "ros":
        import rospy
        rospy.init_node("evaluate_monoped", anonymous=True)
    env = MonopedEnv(backend=args.backend, params=params, seed=args.seed)
    greedy, random_policy = greedy_and_random(env, env.monoped_state.get_state_as_string, qlearn, args.episodes,
                                              args.seed, run_episodes)
    print(json.dumps({"episodes": args.episodes, "horizon_steps": args.horizon, "greedy": greedy,
                      "random": random_policy}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
