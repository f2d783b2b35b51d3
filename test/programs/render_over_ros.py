"""Run by test_rendering_over_ros.py as its own ROS node, against a running sim (seed 0): the same seeded
episode over ROS and on the direct backend must render the same frames (over ROS they come from the
sim node's ~render service), before and after the robot moves; a bad size is one clear error. With
--markers it also collects the contact_markers node's arrows. Prints one JSON line."""
import argparse
import json
import threading
import time
from typing import Any

import numpy as np
import rospy
from visualization_msgs.msg import Marker

import hopper_training
import moving_cube_training
from pybullet_sim.ros.client import SimConnectionError
from robot_rl import TASKS, make_env

MOVES = {"MovingCubeOneDiskWalk-v0": [0] * 12, "Monoped-v0": [3] * 300 + [4] * 300}
assert moving_cube_training and hopper_training  # imported to register their tasks


def timed_render(env) -> tuple:
    start = time.perf_counter()
    frame = env.render()
    return frame, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("env_id")
    parser.add_argument("--markers", action="store_true")
    args = parser.parse_args(rospy.myargv()[1:])
    rospy.init_node("render_over_ros")
    markers, lock = [], threading.Lock()
    if args.markers:
        def on_marker(msg):
            with lock:
                markers.append(msg)
        subscriber = rospy.Subscriber("/pybullet_sim/contact_markers", Marker, on_marker)
        deadline = time.monotonic() + 20.0
        while subscriber.get_num_connections() == 0:  # bounded: the node must be publishing before we step
            if time.monotonic() > deadline:
                raise SystemExit("contact_markers did not connect to /pybullet_sim/contact_markers within 20 s")
            time.sleep(0.02)
    task = TASKS[args.env_id]
    envs = {name: make_env(task, backend=name, seed=0, render_mode="rgb_array") for name in ("ros", "direct")}
    frames, seconds = {}, {}
    try:
        for name, env in envs.items():
            env.reset(seed=0)
            start, start_time = timed_render(env)
            for action in MOVES[args.env_id]:
                env.step(action)
            moved, moved_time = timed_render(env)
            frames[name], seconds[name] = (start, moved), (start_time + moved_time) / 2
        try:
            ros_env: Any = envs["ros"].unwrapped
            ros_env.backend.render(5000, 10)
            bad_size = "no error"
        except SimConnectionError as error:
            bad_size = str(error)
    finally:
        for env in envs.values():
            env.close()
    ros, direct = frames["ros"], frames["direct"]
    with lock:
        arrows = [{"action": m.action, "frame": m.header.frame_id,
                   "length": float(np.linalg.norm([m.points[1].x, m.points[1].y, m.points[1].z])) if m.points else 0.0}
                  for m in markers]
    print(json.dumps({
        "shape": list(ros[0].shape), "dtype": str(ros[0].dtype),
        "equal_to_direct": [bool(np.array_equal(r, d)) for r, d in zip(ros, direct)],
        "changed_pixels": float((np.abs(ros[0].astype(int) - ros[1]).max(axis=2) > 30).mean()),
        "std": float(ros[0].std()), "bad_size": bad_size, "markers": arrows,
        "render_ms_ros": 1000 * seconds["ros"], "render_ms_direct": 1000 * seconds["direct"]}))


if __name__ == "__main__":
    main()
