"""The robots ./ws knows by name (cube, hopper): each one's training package, launch files and ROS namespace.

The one place that maps a robot's name to its packages; ./ws (workspace_tools.cli), the sweeps, the bench and
run_openai_ros_envs read it. Plain strings: reading it imports no robot package.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Robot:
    """A robot as ./ws names it."""

    name: str               # as ./ws run, rviz, sweep, demo take it
    package: str            # its training package: TASKS, launch/main.launch, evaluate.py, policies/
    namespace: str          # its reward topics' namespace (./ws plot /NAMESPACE)
    sim_launch: str         # pybullet_sim's launch file of its sim (./ws rviz)
    default_task: str       # the task main.launch trains unless task:= says otherwise (its package's first)
    task_arg: bool          # whether main.launch takes task:= (the cube's sets its one task itself)
    main_launch: str = "main.launch"  # the training's top-level launch file, in `package`
    sim_package: str = "pybullet_sim"
    show_launch: tuple[str, str] | None = None  # (package, launch file) that ./ws rviz runs: the sim with what
                                                # keeps the robot moving (None: the sim alone)

    @property
    def show(self) -> tuple[str, str]:
        """(package, launch file) that ./ws rviz launches with rviz:=true paused:=false."""
        return self.show_launch or self.sim

    @property
    def training_launch(self) -> tuple[str, str]:
        """(package, launch file) of the training, as roslaunch takes them."""
        return self.package, self.main_launch

    @property
    def sim(self) -> tuple[str, str]:
        """(package, launch file) of the sim alone, as roslaunch takes them."""
        return self.sim_package, self.sim_launch


ROBOTS = {
    "cube": Robot("cube", "moving_cube_training", "moving_cube", "cube_sim.launch", "one_disk_walk", task_arg=False),
    # the monoped falls within a minute alone: ./ws rviz shows it hopping under its controller (docs/guide/hopping.md)
    "hopper": Robot("hopper", "hopper_training", "monoped", "hopper_sim.launch", "stay_up", task_arg=True,
                    show_launch=("hopper_training", "hop_controller.launch")),
}
DEFAULT_ROBOT = "cube"    # ./ws run, rviz and sweep without a robot
DEMO_ROBOT = "hopper"     # ./ws demo without a robot


class UnknownRobot(ValueError):
    """A robot name not in ROBOTS; str() is one line naming the known ones."""


def find_robot(name: str) -> Robot:
    """The robot called `name`; UnknownRobot if there is none."""
    try:
        return ROBOTS[name]
    except KeyError:
        raise UnknownRobot(f"unknown robot '{name}' (known: {', '.join(ROBOTS)})") from None


def robot_of_package(package: str) -> Robot:
    """The robot whose training package is `package`; UnknownRobot if none."""
    for robot in ROBOTS.values():
        if robot.package == package:
            return robot
    raise UnknownRobot(f"no robot trains with package '{package}' (known: "
                       f"{', '.join(robot.package for robot in ROBOTS.values())})")
