"""A live plot of a training run's reward topics, for machines without rqt_plot (Debian 12 packages no rqt).

  rosrun robot_rl plot_rewards.py [NAMESPACE] [--output PNG] [--steps N]

Subscribes to NAMESPACE/reward and NAMESPACE/episode_reward (std_msgs/Float64; NAMESPACE /moving_cube,
the default, or /monoped) and redraws twice a second: the last N (2000) step rewards, and every
episode's return with its moving average over 50 episodes. Without --output it opens a window
(matplotlib's TkAgg: `./ws plot` installs Debian's python3-tk); with --output it rewrites that PNG at
each redraw instead, with no display. Ctrl-C ends it, printing how many messages it received.
Where rqt_plot exists, `rqt_plot NAMESPACE/reward/data NAMESPACE/episode_reward/data` shows the same.
"""
from __future__ import annotations

import argparse
import collections
import io
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import rospy
from std_msgs.msg import Float64

from pybullet_sim.ros.shutdown import shutdown_on_signals

from .atomic import write_bytes_atomic
from .runs.plots import MOVING_AVERAGE, moving_average

REDRAW_S = 0.5


class RewardPlot:
    """The received rewards and a matplotlib figure of them."""

    def __init__(self, namespace: str, steps: int, figure: Any):
        self.namespace = namespace.rstrip("/")
        self.rewards: collections.deque[float] = collections.deque(maxlen=steps)
        self.returns: list[float] = []
        self.received = {"reward": 0, "episode_reward": 0}
        self._lock = threading.Lock()
        self.figure = figure
        self.axes = figure.subplots(2, 1)
        for name in self.received:
            rospy.Subscriber(f"{self.namespace}/{name}", Float64, self._on_message, callback_args=name)

    def _on_message(self, msg: Float64, name: str) -> None:
        with self._lock:
            (self.rewards.append if name == "reward" else self.returns.append)(msg.data)
            self.received[name] += 1

    def draw(self) -> None:
        with self._lock:
            rewards, returns = list(self.rewards), list(self.returns)
        steps_ax, episodes_ax = self.axes
        steps_ax.clear()
        steps_ax.plot(rewards, linewidth=0.8)
        steps_ax.set_title(f"{self.namespace}/reward (last {len(rewards)} messages)", fontsize="medium")
        episodes_ax.clear()
        episodes = range(1, len(returns) + 1)
        episodes_ax.plot(episodes, returns, ".", markersize=3, label="return")
        if returns:
            episodes_ax.plot(episodes, moving_average(returns), "-", label=f"moving average ({MOVING_AVERAGE})")
            episodes_ax.legend(loc="best", fontsize="small")
        episodes_ax.set_title(f"{self.namespace}/episode_reward", fontsize="medium")
        episodes_ax.set_xlabel("episode (since the plot started)")
        for ax in self.axes:
            ax.grid(True, alpha=0.3)
        self.figure.tight_layout()


def main(argv: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(prog="plot_rewards.py", description=__doc__.splitlines()[0])
    parser.add_argument("namespace", nargs="?", default="/moving_cube", help="/moving_cube (default) or /monoped")
    parser.add_argument("--output", type=Path, help="rewrite this PNG at each redraw instead of opening a window")
    parser.add_argument("--steps", type=int, default=2000, help="step rewards shown (default 2000)")
    args = parser.parse_args(argv)
    if args.steps < 1:
        parser.error("--steps must be >= 1")
    if args.output is not None and not args.output.parent.is_dir():
        parser.error(f"--output: the folder {str(args.output.parent)!r} does not exist")
    import matplotlib
    try:
        matplotlib.use("Agg" if args.output else "TkAgg")
    except ImportError as error:  # a window needs Debian's python3-tk
        parser.exit(1, f"plot_rewards.py: no window without python3-tk ({error}); run ./ws plot, or use --output\n")
    import matplotlib.pyplot as plt
    rospy.init_node("plot_rewards", anonymous=True, disable_signals=True)
    shutdown_on_signals()  # Ctrl-C shuts rospy down (in a thread, never in the handler): both loops below end
    figure = plt.figure(figsize=(8, 6))
    plot = RewardPlot(args.namespace, args.steps, figure)
    if args.output is None:
        from matplotlib.animation import FuncAnimation

        def redraw(_frame: int) -> None:
            if rospy.is_shutdown():
                plt.close(figure)  # ends plt.show(), from the GUI's own thread
            else:
                plot.draw()
        _animation = FuncAnimation(figure, redraw, interval=REDRAW_S * 1000, cache_frame_data=False)
        plt.show()
    else:
        while not rospy.is_shutdown():
            plot.draw()
            buffer = io.BytesIO()
            figure.savefig(buffer, format="png", dpi=80)
            write_bytes_atomic(args.output, buffer.getvalue())
            rospy.rostime.wallsleep(REDRAW_S)
    print(f"received {plot.received['reward']} rewards and {plot.received['episode_reward']} episode rewards "
          f"on {plot.namespace}", flush=True)
    return 0

