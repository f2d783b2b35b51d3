"""The sim node against a real master: same seed -> same odom stream; bad input -> one clear error."""
import json
from pathlib import Path

import pytest
import yaml

from moving_cube_training.one_disk_walk import MOVING_CUBE

from conftest import REPO, RosMaster, launch_args

CUBE_URDF = MOVING_CUBE.urdf_path.read_text()
CUBE_SIM = yaml.safe_load(MOVING_CUBE.sim_config_path.read_text())


def record_odom(master: RosMaster, seed: int) -> list:
    master.start(["roslaunch", "pybullet_sim", "cube_sim.launch",
                  *launch_args(paused="true", real_time_factor=0, seed=seed)])
    result = master.run(["python", str(Path(__file__).with_name("record_odom.py")), "100"], timeout=120)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_two_runs_with_the_same_seed_give_identical_odom_streams(tmp_path):
    streams = []
    for run, seed in enumerate((7, 7, 8)):
        master = RosMaster(tmp_path / f"run{run}", cwd=REPO)
        try:
            streams.append(record_odom(master, seed))
        finally:
            master.close()
    assert len(streams[0]) == 100
    assert streams[0] == streams[1]
    assert streams[0] != streams[2], "a different seed should give different noise"


def start_sim(master: RosMaster, private_params: dict, robot_description=None):
    """Run the sim node alone with the given params; return its completed process (it should exit)."""
    if robot_description is not None:
        master.params.setParam("/robot_description", robot_description)
    master.params.setParam("/pybullet_sim", private_params)
    return master.run(["rosrun", "pybullet_sim", "sim_node.py"], timeout=60)


def with_controller_joint(joint: str) -> dict:
    params = yaml.safe_load(yaml.safe_dump(CUBE_SIM))
    params["controllers"]["inertia_wheel_roll_joint_velocity_controller"]["joint"] = joint
    return params


@pytest.mark.parametrize("description, params, expected", [
    (None, CUBE_SIM, "parameter /robot_description is missing"),
    ("<robot name='cube'><link name='a'>", CUBE_SIM, "parameter /robot_description is not valid XML"),
    ("<sdf version='1.6'/>", CUBE_SIM, "is not a URDF"),
    (CUBE_URDF, with_controller_joint("no_such_joint"), "names joint 'no_such_joint'"),
    (CUBE_URDF, {**CUBE_SIM, "time_step": "fast"}, "parameter ~time_step must be float"),
], ids=["missing_description", "broken_xml", "not_urdf", "unknown_joint", "mistyped_param"])
def test_bad_input_stops_the_node_with_one_clear_error(ros_master, description, params, expected):
    result = start_sim(ros_master, params, description)
    assert result.returncode == 1
    errors = [line for line in result.stderr.splitlines() if line.startswith("pybullet_sim cannot start:")]
    assert len(errors) == 1 and expected in errors[0], result.stderr
