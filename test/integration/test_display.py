"""What needs a display, on Xvfb (Debian's, installed by ./ws test): each robot's saved rviz config loads
without errors and its screenshot shows the robot; render_mode="human" opens PyBullet's window, shows
the robot and runs no faster than real time. Screenshots are kept in the test's tmp_path."""
import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import ImageGrab

from conftest import Processes, launch_args

HUMAN = Path(__file__).with_name("human_render.py")
# Debian's rviz asks rospack for the media_export package (not packaged in Debian) and says so on every
# start; nothing else in an rviz log may say error.
DEBIAN_RVIZ_NOISE = ("[rospack] Error: no such package media_export", "[librospack]: error while executing command")
SHOW_ROBOT_TIMEOUT = 120.0  # wall s: rviz starts on a software OpenGL (llvmpipe) on 2 busy cores


def colour_counts(image: np.ndarray) -> dict:
    """Pixels of the robots' colours (see test/unit/test_rendering.py); rviz's background is light grey."""
    r, g, b = (image[..., i].astype(int) for i in range(3))
    return {"red": int(((r > 120) & (g < 60) & (b < 60)).sum()), "dark": int((image.max(axis=2) < 60).sum()),
            "blue": int(((b > 100) & (r < 80) & (g < 100)).sum())}


@pytest.mark.parametrize("robot, wanted", [("cube", {"red": 1500, "dark": 1500}),
                                           ("hopper", {"red": 800, "blue": 200})])
def test_rviz_config_loads_without_errors_and_shows_the_robot(ros_master, xvfb, tmp_path, robot, wanted):
    ros_master.env["DISPLAY"] = xvfb
    log = tmp_path / "roslaunch.log"
    with open(log, "w") as out:
        launch = ros_master.start(["roslaunch", "pybullet_sim", f"{robot}_sim.launch",
                                   *launch_args(rviz="true", paused="false")], stdout=out, stderr=subprocess.STDOUT)
    screenshot = tmp_path / f"rviz_{robot}.png"
    deadline = time.monotonic() + SHOW_ROBOT_TIMEOUT
    while True:  # bounded poll: rviz has no "drawn" signal; a screenshot shows when the robot is there
        image = np.asarray(ImageGrab.grab(xdisplay=xvfb))
        counts = colour_counts(image)
        if all(counts[colour] >= n for colour, n in wanted.items()):
            break
        if launch.poll() is not None or time.monotonic() > deadline:
            ImageGrab.Image.fromarray(image).save(screenshot)
            raise AssertionError(f"rviz did not show the {robot} within {SHOW_ROBOT_TIMEOUT} s ({counts}, wanted "
                                 f"{wanted}); see {screenshot} and {log}:\n{log.read_text()[-3000:]}")
        time.sleep(0.5)
    ImageGrab.Image.fromarray(image).save(screenshot)
    output = log.read_text()
    assert launch.poll() is None and "has died" not in output, output[-3000:]
    errors = [line for line in output.splitlines()
              if re.search(r"error|fatal", line, re.I) and not line.startswith(DEBIAN_RVIZ_NOISE)]
    assert errors == [], f"rviz or a node logged errors (screenshot {screenshot}):\n" + "\n".join(errors)
    assert "process[rviz-" in output and "process[contact_markers-" in output


def test_human_mode_shows_pybullets_window_in_real_time(xvfb, tmp_path):
    runner = Processes(tmp_path, DISPLAY=xvfb)
    screenshot = tmp_path / "human.png"
    try:
        result = runner.run([sys.executable, str(HUMAN), str(screenshot)], timeout=180)
    finally:
        runner.close()
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["warnings"] == [], "gymnasium's env checker (with its render checks) complained"
    assert report["render_returned"] == ["None"], "render() returns nothing in human mode"
    assert report["wall_s"] >= report["sim_s"], "human mode must not run faster than real time"
    assert report["red"] > 1000 and report["dark"] > 1000, f"the window should show the cube ({report}, {screenshot})"
