"""plot_rewards.py, the live plot of the reward topics (Debian 12 has no rqt_plot): headless it keeps a
PNG of a real training run's rewards; with a display (Xvfb) it opens a window; Ctrl-C ends it cleanly."""
import re
import signal
import subprocess
import time

import numpy as np
import yaml
from PIL import Image, ImageGrab

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from workspace_tools.processes import launch_args, wait_for


def subscribed(master, topics) -> bool:
    _, subscribers, _ = master.params.getSystemState()
    return all(any(node.startswith("/plot_rewards") for node in dict(subscribers).get(t, [])) for t in topics)


def stop_plot(plot: subprocess.Popen) -> str:
    plot.send_signal(signal.SIGINT)
    stdout, stderr = plot.communicate(timeout=30)
    assert plot.returncode == 0, stdout + stderr
    return stdout


def test_headless_plot_of_a_training_run(ros_master, tmp_path):
    png = tmp_path / "rewards.png"
    plot = ros_master.start(["rosrun", "robot_rl", "plot_rewards.py", "/moving_cube", "--output", str(png)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for(lambda: subscribed(ros_master, ["/moving_cube/reward", "/moving_cube/episode_reward"]), 30,
             "plot_rewards.py subscribing to the reward topics")
    document = yaml.safe_load(ONE_DISK_WALK.config_path.read_text())
    # Angle limits out of reach: 20 episodes of 50 steps, long enough for the training node's publishers
    # to connect to the plot (rospy drops what a publisher sends before a subscriber has connected).
    document["moving_cube"].update(nepisodes=20, nsteps=50, max_pitch_angle=10.0, max_yaw_angle=10.0)
    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump(document))
    training = ros_master.run(["roslaunch", "moving_cube_training", "main.launch", *launch_args(
        config=config, results_dir=tmp_path / "results", video="false")], timeout=180)
    assert training.returncode == 0 and "Training complete: 20 episodes" in training.stdout, training.stdout[-3000:]
    drawn_after_training = time.time()
    wait_for(lambda: png.exists() and png.stat().st_mtime > drawn_after_training, 30, "a redraw of the PNG")
    counts = re.search(r"received (\d+) rewards and (\d+) episode rewards on /moving_cube", stop_plot(plot))
    assert counts, "plot_rewards.py should say what it received"
    steps = sum(int(line.split(",")[1]) for line in
                (tmp_path / "results/moving_cube/latest/episodes.csv").read_text().splitlines()[1:])
    assert steps == 20 * 50
    # A publisher's first messages can go out before it has connected to the plot; the last ones cannot.
    assert steps / 2 < int(counts[1]) <= steps and 10 <= int(counts[2]) <= 20, counts[0]
    image = np.asarray(Image.open(png).convert("RGB"))
    assert image.shape == (480, 640, 3) and image.std() > 10


def test_window_plot_opens_on_a_display(ros_master, xvfb):
    ros_master.env["DISPLAY"] = xvfb
    plot = ros_master.start(["rosrun", "robot_rl", "plot_rewards.py", "/monoped"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)

    def window_shown() -> bool:  # Xvfb's root window is black; the plot's window is mostly white
        assert plot.poll() is None, plot.communicate()
        return (np.asarray(ImageGrab.grab(xdisplay=xvfb)).min(axis=2) > 200).mean() > 0.2
    wait_for(window_shown, 60, "the plot's window on the display")
    assert "received 0 rewards and 0 episode rewards on /monoped" in stop_plot(plot)
