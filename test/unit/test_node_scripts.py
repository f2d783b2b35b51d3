"""The sim node's scripts stopped while they start: SIGINT during their imports (roslaunch stops every node
when a required one fails fast) ends them quietly, with no KeyboardInterrupt traceback. The imports are held
by a stand-in `rospy` module that says so and waits, so the signal lands inside an import every time."""
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from robot_rl import default_sigint

SCRIPTS = Path(__file__).resolve().parents[2] / "pybullet_sim" / "scripts"
HOLD_IMPORT = "print('importing rospy', flush=True)\nimport time\ntime.sleep(60)\n"


@pytest.mark.parametrize("script", ["sim_node.py", "contact_markers.py"])
def test_sigint_while_the_node_imports_ends_it_without_a_traceback(tmp_path, script):
    (tmp_path / "rospy.py").write_text(HOLD_IMPORT)
    env = {"PYTHONPATH": f"{tmp_path}:{':'.join(sys.path[1:])}", "PATH": "/usr/bin:/bin"}
    node = subprocess.Popen([sys.executable, str(SCRIPTS / script)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
    try:
        assert node.stdout is not None and node.stdout.readline() == "importing rospy\n"
        node.send_signal(signal.SIGINT)
        _, errors = node.communicate(timeout=10)
    finally:
        node.kill()
        node.wait(10)
    assert "Traceback" not in errors and "KeyboardInterrupt" not in errors, errors
    assert node.returncode == -signal.SIGINT
