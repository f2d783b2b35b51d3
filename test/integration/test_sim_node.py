"""The sim node against a real master: the same seed gives the same odom stream (bad input: test_faults.py)."""
import json

import yaml

from moving_cube_training.robot import MOVING_CUBE
from workspace_tools.paths import PROGRAMS, REPO
from workspace_tools.processes import RosMaster, launch_args

CUBE_URDF = MOVING_CUBE.urdf_path.read_text()
CUBE_SIM = yaml.safe_load(MOVING_CUBE.sim_config_path.read_text())


def record_odom(master: RosMaster, seed: int) -> list:
    master.start(["roslaunch", "pybullet_sim", "cube_sim.launch",
                  *launch_args(paused="true", real_time_factor=0, seed=seed)])
    result = master.run(["python", str(PROGRAMS / "record_odom.py"), "100"], timeout=120)
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


def test_step_and_reset_answer_with_the_messages_they_publish_or_their_packed_values(tmp_path):
    master = RosMaster(tmp_path, cwd=REPO)
    try:
        master.start(["roslaunch", "pybullet_sim", "hopper_sim.launch", *launch_args(paused="true")])
        result = master.run(["python", str(PROGRAMS / "readings_client.py")], timeout=120)
    finally:
        master.close()
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    every = {"joint_states": True, "odometry": True, "imu": True, "contacts": True}
    assert report["reset"] == every and report["step"] == every
    # Packed: the same values as the messages published on the topics (subscribed here), contacts included.
    for step in report["packed_steps"]:
        assert step == {**every, "contact_points": step["contact_points"]}
    assert report["packed_steps"][-1]["contact_points"] >= 1, "the standing hopper's foot should touch the ground"
    assert report["packed_reset"] == {**every, "contact_points": report["packed_reset"]["contact_points"]}
    assert report["stamp"] == 0.2
    # ~step_packed advanced exactly 50 physics steps a call; values[0] is the new sim time.
    assert [round(stamp, 9) for stamp in report["packed_stamps"]] == \
        [round(0.2 + 0.05 * k, 9) for k in range(1, len(report["packed_stamps"]) + 1)]
    # The commands in the request moved the joints towards their targets within 0.2 s (PID p = 10).
    assert report["positions"][0] > 0.1 and report["positions"][1] < -0.05 and report["positions"][2] < -0.1
    for service, errors in (("/pybullet_sim/step:", report["errors"][:2]), ("/pybullet_sim/step_packed:",
                                                                            report["errors"][2:])):
        assert f"{service} no controller named no_such_controller (controllers: haa_joint_position_controller" \
            in errors[0]
        assert f"{service} controllers and commands differ in length" in errors[1]
