"""The monoped's hop can be seen in its frames (direct backend, no ROS): its camera (hopper_sim.yaml) follows the
base's x and y only, so a flight lifts the foot off the ground in the picture, the foot is marked green while it
touches the ground, a dark disc on the ground under it shows the gap, and the scene's height poles are drawn.
The scene is pybullet_sim.scene."""
import math

import numpy as np
import pytest

import hopper_training
from pybullet_sim.config import parse_camera
from pybullet_sim.errors import ConfigError
from robot_rl import make_env

HOP_IN_PLACE = next(task for task in hopper_training.TASKS if task.name == "hop_in_place")
FOOT = "lowerleg_contactsensor_link"
CONTACT = "lowerleg_contactsensor_sensor"
WIDTH, HEIGHT = 640, 480
PLUS_2_CM = 2  # the action that places the foot 2 cm ahead every hop (the constant policy that stays upright)


def green(frame):
    """Pixels of the contact colour, lit or shaded."""
    r, g, b = (frame[..., i].astype(int) for i in range(3))
    return (g > r + 50) & (g > b + 50)


def red(frame):
    """Pixels of the foot's own red (and the base's), lit or shaded."""
    r, g, b = (frame[..., i].astype(int) for i in range(3))
    return (r > g + 50) & (r > b + 50)


@pytest.fixture(scope="module")
def stance_and_flight():
    """After 3 hops of the hop cycle, a frame 20 ms into a stance (the foot on the ground) and one at the top of
    the next flight; each with (sim time, the foot's height in m, whether it touched the ground)."""
    env = make_env(HOP_IN_PLACE, backend="direct", seed=0, render_mode="rgb_array", render_width=WIDTH,
                   render_height=HEIGHT)
    world = env.unwrapped.backend.world
    sensor = next(s for s in world.config.sensors if s.name == CONTACT)
    seen, frames = [], {}  # seen: (time, foot height, touching) every 1 ms of the 4th and 5th hops

    def look():
        seen.append((world.time, world.link_pose(FOOT)[0][2], bool(world.read_sensor(sensor).contacts)))
        touching = [state[2] for state in seen]
        if "stance" not in frames and touching[-20:] == [True] * 20:
            frames["stance"] = (env.render(), seen[-1])
        elif "stance" in frames and "flight" not in frames and not touching[-1] and seen[-1][1] < seen[-2][1]:
            frames["flight"] = (env.render(), seen[-1])  # the first period after the apex

    try:
        env.reset(seed=0)
        for _ in range(3):
            env.step(PLUS_2_CM)
        env.unwrapped.period_hooks.append(look)
        for _ in range(2):
            env.step(PLUS_2_CM)
    finally:
        env.close()
    assert set(frames) == {"stance", "flight"}, f"no stance and flight in the 4th and 5th hops: {seen[::20]}"
    return frames


def foot_bottom_row(mask, rows_below):
    """The lowest image row of the foot's pixels in `mask`, searching below row `rows_below` (under the base)."""
    rows = np.nonzero(mask[rows_below:].any(axis=1))[0]
    assert rows.size, "no foot pixels below the body"
    return rows_below + int(rows.max())


def test_a_flight_frame_shows_the_foot_off_the_ground_and_a_stance_frame_marks_contact(stance_and_flight):
    (stance, (_, stance_z, stance_touching)) = stance_and_flight["stance"]
    (flight, (_, flight_z, flight_touching)) = stance_and_flight["flight"]
    assert stance_touching and not flight_touching
    gap = flight_z - stance_z
    assert gap > 0.03, f"the controller's flight should lift the foot 3 cm or more, got {gap:.3f} m"
    # camera: distance 1.4 m, fov 60, aim at 0.6 m: pixels per metre at the robot's depth, and the row of 0.4 m
    per_metre = HEIGHT / (2 * 1.4 * math.tan(math.radians(30)))
    below_body = int(HEIGHT / 2 + 0.2 * per_metre)
    assert green(stance)[below_body:].sum() > 10, "in stance the foot is marked green"
    assert green(flight)[below_body:].sum() == 0, "in flight the foot is not marked"
    lifted = foot_bottom_row(green(stance), below_body) - foot_bottom_row(red(flight), below_body)
    assert lifted >= 0.7 * gap * per_metre, (
        f"the foot rose {gap * 100:.1f} cm ({gap * per_metre:.0f} px) but its picture only {lifted} px: "
        "the camera must not follow the base's height")
    # the ground mark (a dark disc straight under the foot) shows below the foot in flight, ground between them
    bottom = foot_bottom_row(red(flight), below_body)
    columns = np.nonzero(red(flight)[bottom])[0]
    under = flight[bottom + 1:, columns.min():columns.max() + 1].max(axis=2) < 100
    mark_rows = np.nonzero(under.any(axis=1))[0]
    assert mark_rows.size and mark_rows.min() >= 3, f"no ground mark a gap below the flying foot: {mark_rows[:5]}"


def test_the_height_poles_are_drawn_in_dark_and_light_bands(stance_and_flight):
    frame = stance_and_flight["stance"][0]
    dark = frame.max(axis=2) < 60
    columns = dark.sum(axis=0)
    assert (columns > 20).sum() >= 4, "two poles' dark bands should stand in the picture"
    column = int(np.argmax(columns))
    changes = np.count_nonzero(np.diff(dark[:, column].astype(int)))
    assert changes >= 8, f"a pole should alternate dark and light bands, found {changes} edges"


def test_camera_scene_options_are_checked():
    camera = parse_camera({"follow": "horizontal", "target_height": 0.5, "shadows": True,
                           "contact_color": [0, 1, 0, 1], "poles": {"xs": [0, 1], "y": 0.3}}, "~/camera")
    assert camera.follow == "horizontal" and camera.poles.xs == (0.0, 1.0) and camera.contact_color == (0, 1, 0, 1)
    for section, message in (({"follow": "up"}, r"~/camera/follow must be one of base, horizontal, fixed"),
                             ({"contact_color": [0, 1, 0]}, r"~/camera/contact_color must be \[\] or RGBA"),
                             ({"light_direction": [0, 0, 0]}, "must not be all zeros"),
                             ({"poles": {"xs": [0, "a"]}}, r"~/camera/poles/xs must be a list of finite numbers"),
                             ({"poles": {"band": 0.0}}, r"~/camera/poles/band must be >= 0.01"),
                             ({"poles": {"colour": 1}}, r"~/camera/poles has unknown keys \['colour'\]")):
        with pytest.raises(ConfigError, match=message):
            parse_camera(section, "~/camera")
