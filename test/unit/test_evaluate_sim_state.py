"""evaluate.py on the direct backend when the sim's state blows up: one line and exit code 1, as over ROS.
The blow-up is real PyBullet's: a NaN velocity set on the cube's base before the first step."""
import math

import pybullet as p
import pytest

from moving_cube_training import TASKS
from robot_rl import DirectBackend, evaluation
from workspace_tools.paths import REPO

DEMO_RUN = REPO / "moving_cube_training" / "policies" / "demo"


def test_non_finite_readings_on_the_direct_backend_end_evaluate_with_one_line(monkeypatch, capsys):
    step = DirectBackend.step

    def blown_up_step(self: DirectBackend, physics_steps: int):
        world = self.world
        p.resetBaseVelocity(world._body, (math.nan, 0.0, 0.0), (0.0, 0.0, 0.0), physicsClientId=world._cid)
        return step(self, physics_steps)

    monkeypatch.setattr(DirectBackend, "step", blown_up_step)
    with pytest.raises(SystemExit) as exit_:
        evaluation.main(["--qtable", str(DEMO_RUN), "--episodes", "1", "--backend", "direct"], TASKS, "evaluate_test")
    assert exit_.value.code == 1
    out, err = capsys.readouterr()
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("evaluate.py: the sim's state is no longer finite at sim time "), err
    assert "restart the sim" in lines[0]
