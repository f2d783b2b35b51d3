"""Run openai_ros's own task env for the cube or the hopper on the PyBullet sim, with random actions.

  run_openai_ros_envs.py cube|hopper OPENAI_ROS_WS [--episodes N] [--steps N] [--seed N] [--timeout S]

OPENAI_ROS_WS is a catkin workspace in which The Construct's openai_ros (ROS 1) is built (its
`RLExperimentInfo` message must be generated: the envs import it). The script does what a user of
openai_ros does, and nothing in its place: a node, the `ros_ws_abspath` param, then
`StartOpenAI_ROS_Environment(ENV_ID)`, whose task env launches `start_world.launch` and
`put_robot_in_world.launch` (moving_cube_description's, or legged_robots_sims') from this workspace,
which start the sim; then gym's reset/step. It needs their era's gym and GitPython (openai_ros imports
both), so run it with a python that has them, inside `./ws exec`, against a running master
(docs/guide/tutorials.md). One JSON line per episode; exit 0, or 1 (one line saying why, or openai_ros's
traceback). Everything the env launched is ended when the script ends.
"""
import argparse
import importlib
import json
import os
import random
import sys
import threading
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import rosgraph
import rospkg
import rospy

from workspace_tools.launch_reaper import MARK_VARIABLE, end_marked_processes, watch_launch
from workspace_tools.robots import ROBOTS


@dataclass(frozen=True)
class OpenAIRosEnv:
    env_id: str
    namespace: str        # where the task env reads `ros_ws_abspath` and loads its task YAML
    world_package: str    # the package whose start_world.launch the task env runs


ENVS = {
    "cube": OpenAIRosEnv("MovingCubeOneDiskWalk-v0", ROBOTS["cube"].namespace, "moving_cube_description"),
    "hopper": OpenAIRosEnv("HopperStayUp-v0", ROBOTS["hopper"].namespace, "legged_robots_sims"),
}


class Watchdog:
    """openai_ros's waits have no bound: if the run makes no progress for `timeout` s, say where it
    was, end what it launched and exit 1."""

    def __init__(self, timeout: float, env_id: str):
        self.timeout, self.env_id, self.phase = timeout, env_id, "start"
        self._timer: threading.Timer | None = None

    def at(self, phase: str) -> None:
        self.phase = phase
        if self._timer:
            self._timer.cancel()
        self._timer = threading.Timer(self.timeout, self._expire)
        self._timer.daemon = True
        self._timer.start()

    def stop(self) -> None:
        if self._timer:
            self._timer.cancel()

    def _expire(self) -> None:
        print(f"{self.env_id}: no progress within {self.timeout} s during {self.phase} (openai_ros waits without a "
              f"bound; its log above says on what)", file=sys.stderr, flush=True)
        end_marked_processes(os.environ[MARK_VARIABLE])
        os._exit(1)


def use_openai_ros(workspace: Path) -> None:
    """Make the built openai_ros importable and findable by rospkg (its task envs load their YAML with it)."""
    messages = workspace / "devel" / "lib" / "python3" / "dist-packages"
    if not (messages / "openai_ros" / "msg").is_dir():
        sys.exit(f"run_openai_ros_envs: {workspace} has no built openai_ros ({messages / 'openai_ros' / 'msg'} "
                 f"is missing): build it there first, as its README says")
    sys.path.insert(0, str(messages))
    os.environ["ROS_PACKAGE_PATH"] = f"{workspace / 'src'}:{os.environ.get('ROS_PACKAGE_PATH', '')}"


def run(spec: OpenAIRosEnv, episodes: int, steps: int, seed: int, watchdog: Watchdog) -> None:
    rospy.init_node("openai_ros_envs")
    # openai_ros starts its two roslaunch at once: on a master without /run_id (rosmaster alone, not
    # roscore) each would set its own, and the second one refuses to start ("run_id ... does not match").
    if not rospy.has_param("/run_id"):
        rospy.set_param("/run_id", str(uuid.uuid1()))
    # openai_ros wants the launch files' package inside ros_ws_abspath, else it clones its own.
    package = Path(rospkg.RosPack().get_path(spec.world_package))
    rospy.set_param(f"/{spec.namespace}/ros_ws_abspath", str(package.parent))
    common = importlib.import_module("openai_ros.openai_ros_common")
    watchdog.at("StartOpenAI_ROS_Environment")
    env = common.StartOpenAI_ROS_Environment(spec.env_id)
    if env is None:
        sys.exit(f"run_openai_ros_envs: openai_ros did not register {spec.env_id}")
    actions = random.Random(seed)
    for episode in range(episodes):
        started = time.monotonic()
        watchdog.at(f"reset of episode {episode}")
        observation = first = env.reset()
        total, done, step = 0.0, False, 0
        while step < steps and not done:
            watchdog.at(f"step {step} of episode {episode}")
            observation, reward, done, _ = env.step(actions.randrange(env.action_space.n))
            total += reward
            step += 1
        print(json.dumps({"env": spec.env_id, "episode": episode, "steps": step, "return": total, "done": done,
                          "first_observation": list(first), "last_observation": list(observation),
                          "seconds": round(time.monotonic() - started, 1)}), flush=True)


def positive(kind):
    def parse(text: str):
        value = kind(text)
        if not value > 0:
            raise argparse.ArgumentTypeError(f"{text} is not above 0")
        return value
    return parse


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("robot", choices=sorted(ENVS))
    parser.add_argument("openai_ros_ws", type=Path, help="a catkin workspace with openai_ros built")
    parser.add_argument("--episodes", type=positive(int), default=3)
    parser.add_argument("--steps", type=positive(int), default=20, help="most steps per episode")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random actions")
    parser.add_argument("--timeout", type=positive(float), default=120.0, help="most seconds without progress")
    args = parser.parse_args()
    spec = ENVS[args.robot]
    use_openai_ros(args.openai_ros_ws.resolve())
    if not rosgraph.is_master_online():
        sys.exit(f"run_openai_ros_envs: no ROS master at {rosgraph.get_master_uri()}: start one (./ws exec roscore)")
    watch_launch()  # what the env launches is marked, and ended when this process ends however it ends
    watchdog = Watchdog(args.timeout, spec.env_id)
    try:
        run(spec, args.episodes, args.steps, args.seed, watchdog)
    finally:
        watchdog.stop()
        end_marked_processes(os.environ[MARK_VARIABLE])
    return 0


if __name__ == "__main__":
    sys.exit(main())
