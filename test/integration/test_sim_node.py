"""The sim node against a real master: the same seed gives the same odom stream (bad input: test_faults.py)."""
import json
from pathlib import Path

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
