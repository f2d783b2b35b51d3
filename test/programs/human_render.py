"""Run by test_display.py with DISPLAY on an Xvfb: gymnasium's env checker with its render checks (it
makes an env of each render mode in turn; "human" opens PyBullet's window, one at a time per process),
then human-mode steps of the cube, which run no faster than real time, a screenshot of the window
(saved to the path given), and three resets, whose landing must not be replayed. Prints one JSON line."""
import json
import os
import sys
import time
import warnings
from typing import Any

import numpy as np
from gymnasium.utils.env_checker import check_env
from PIL import ImageGrab

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import make_env

STEPS = 20


def main(screenshot: str) -> None:
    checked = make_env(ONE_DISK_WALK, backend="direct", render_mode="rgb_array")
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(checked.unwrapped)
    finally:
        checked.close()
    env = make_env(ONE_DISK_WALK, backend="direct", render_mode="human")
    try:
        start = time.monotonic()  # before reset(), which (human mode) starts the env's real-time pacing
        env.reset(seed=0)
        returned: list[Any] = [env.step(0) is not None and env.render() for _ in range(STEPS)]
        wall = time.monotonic() - start
        image = np.asarray(ImageGrab.grab(xdisplay=os.environ["DISPLAY"]))
        world = env.unwrapped.backend.world  # type: ignore[attr-defined]
        replay = world.replay_from_reset
        replayed: list[bool] = []

        def recorded(count: int) -> bool:  # in the window the mouse can move the robot: no start is replayed
            replayed.append(replay(count))
            return replayed[-1]
        world.replay_from_reset = recorded
        for _ in range(3):
            env.reset()
    finally:
        env.close()
    ImageGrab.Image.fromarray(image).save(screenshot)
    r, g, b = (image[..., i].astype(int) for i in range(3))
    print(json.dumps({"warnings": [str(w.message) for w in caught if "infinity" not in str(w.message)],
                      "render_returned": sorted({repr(value) for value in returned}),
                      "replayed": replayed,
                      "sim_s": STEPS * ONE_DISK_WALK.default_params().running_step, "wall_s": wall,
                      "red": int(((r > 120) & (g < 60) & (b < 60)).sum()),
                      "dark": int((image.max(axis=2) < 60).sum())}))


if __name__ == "__main__":
    main(sys.argv[1])
