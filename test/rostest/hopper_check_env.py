"""Run by hopper_sim_node.py as its own process and ROS node, with a fresh env: gymnasium's check_env
over ROS, then a seeded episode of 200 fixed actions over ROS must give exactly the observations of
the direct backend (an in-process World with the sim launch's seed 0). Prints one line per check."""
import dataclasses

import gymnasium
import numpy as np
import rospy
from gymnasium.utils.env_checker import check_env

from hopper_training.envs.stay_up import STAY_UP

ACTIONS = [int(a) for a in np.random.default_rng(7).integers(0, 6, size=200)]


def episode(env):
    observation, _ = env.reset(seed=0)
    observations = [observation]
    for action in ACTIONS:
        observation, _, terminated, truncated, _ = env.step(action)
        observations.append(observation)
        if terminated or truncated:
            break
    return np.array(observations)


def main():
    rospy.init_node("hopper_check_env")
    params = dataclasses.replace(STAY_UP.default_params(), running_step=0.001)  # 200 steps stay up at 1 ms
    env = gymnasium.make(STAY_UP.env_id, backend="ros", params=params).unwrapped
    direct_env = gymnasium.make(STAY_UP.env_id, backend="direct", seed=0, params=params).unwrapped
    try:
        check_env(env, skip_render_check=True)
        print("check_env passed")
        over_ros, direct = episode(env), episode(direct_env)
    finally:
        env.close()
        direct_env.close()
    assert over_ros.shape == direct.shape == (201, 10), (over_ros.shape, direct.shape)
    assert np.abs(over_ros - over_ros[0]).max() > 1e-3, "the actions should change the observations"
    difference = float(np.abs(over_ros - direct).max())
    assert difference <= 1e-9, f"ROS and direct observations differ by {difference}"
    print("ROS matches direct")


if __name__ == "__main__":
    main()
