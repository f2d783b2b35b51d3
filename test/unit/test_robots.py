"""workspace_tools.robots, the one map from a robot's name to its packages: every entry names what exists (the
training package and its default task, main.launch and whether it takes task:=, the sim launch file)."""
import importlib
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest
import rospkg

from workspace_tools.robots import DEFAULT_ROBOT, DEMO_ROBOT, ROBOTS, UnknownRobot, find_robot, robot_of_package


def launch_file(package: str, name: str) -> Path:
    path = Path(rospkg.RosPack().get_path(package)) / "launch" / name
    assert path.is_file(), f"{package}/launch/{name} does not exist"
    return path


@pytest.mark.parametrize("name", ROBOTS)
def test_each_robot_names_its_package_launch_files_and_default_task(name):
    robot = ROBOTS[name]
    assert robot.name == name
    tasks = importlib.import_module(robot.package).TASKS
    assert tasks[0].name == robot.default_task  # the package's first task is main.launch's default
    assert tasks[0].robot.sim_launch == f"roslaunch {robot.sim_package} {robot.sim_launch}"
    launch_file(*robot.sim)
    declared = {arg.get("name"): arg for arg in ElementTree.parse(launch_file(*robot.training_launch)).iter("arg")}
    assert ("task" in declared and declared["task"].get("default") is not None) == robot.task_arg
    if robot.task_arg:
        assert declared["task"].get("default") == robot.default_task
    assert all(task.reward_topic.startswith(f"/{robot.namespace}/") for task in tasks)  # ./ws plot /NAMESPACE


def test_names_and_packages_are_looked_up_both_ways():
    assert {DEFAULT_ROBOT, DEMO_ROBOT} <= set(ROBOTS)
    assert find_robot("hopper").package == "hopper_training"
    assert robot_of_package("moving_cube_training").name == "cube"
    with pytest.raises(UnknownRobot, match=r"^unknown robot 'fly' \(known: cube, hopper\)$"):
        find_robot("fly")
    with pytest.raises(UnknownRobot):
        robot_of_package("fly_training")
