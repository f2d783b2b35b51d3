"""Rendering on the direct backend (no ROS master): frames from the camera that follows the robot, the
env's render modes, and videos that decode to the frames they should hold. Over ROS the sim node
renders the same frames (test/integration/test_rendering_over_ros.py)."""
import subprocess
import warnings

import gymnasium
import imageio.v2 as imageio
import imageio_ffmpeg
import numpy as np
import pytest

import hopper_training
import moving_cube_training
from pybullet_sim.config import parse_robot_config
from pybullet_sim.errors import ConfigError
from robot_rl import VideoRecorder, frame_every, make_env

CUBE, STAY_UP, HOP = (*moving_cube_training.TASKS, *hopper_training.TASKS)[:3]
ODOMETRY = "p3d_base_controller"
# Actions that move each robot: the cube spins its wheel up (the reaction rolls it along y), the
# monoped swings its hip (it tips over).
MOVES = {CUBE.env_id: [0] * 12, STAY_UP.env_id: [3] * 300 + [4] * 300}


def robot_pixels(frame: np.ndarray) -> dict:
    """Pixels of the robots' colours: red (the cube's wheel, the monoped's base and foot), dark (the
    cube's body), blue (the monoped's legs). The ground is white and light blue, the sky white."""
    r, g, b = (frame[..., i].astype(int) for i in range(3))
    return {"red": int(((r > 120) & (g < 60) & (b < 60)).sum()), "dark": int((frame.max(axis=2) < 60).sum()),
            "blue": int(((b > 120) & (r < 80) & (g < 100)).sum())}


@pytest.mark.parametrize("task, colours", [(CUBE, ("red", "dark")), (STAY_UP, ("red", "blue"))],
                         ids=["cube", "monoped"])
def test_a_frame_shows_the_robot_and_changes_when_it_moves(task, colours):
    env = make_env(task, backend="direct", seed=0, render_mode="rgb_array")
    try:
        env.reset(seed=0)
        first, again = env.render(), env.render()
        start = np.array(env.unwrapped.readings.odometry(ODOMETRY).position)
        for action in MOVES[task.env_id]:
            env.step(action)
        moved = env.render()
        travelled = np.linalg.norm(np.array(env.unwrapped.readings.odometry(ODOMETRY).position) - start)
    finally:
        env.close()
    assert first.shape == (240, 320, 3) and first.dtype == np.uint8
    assert first.std() > 20.0, "a blank frame"
    for frame in (first, moved):  # the camera follows: the robot stays in the picture
        counts = robot_pixels(frame)
        assert all(counts[colour] > 200 for colour in colours), counts
    assert np.array_equal(first, again), "rendering twice without a step must give the same frame"
    assert travelled > 0.1, f"the actions should move the robot (moved {travelled:.3f} m)"
    changed = (np.abs(first.astype(int) - moved).max(axis=2) > 30).mean()
    assert changed > 0.05, f"only {changed:.1%} of the pixels changed although the robot moved {travelled:.2f} m"


def test_rendering_changes_nothing_in_the_simulation():
    actions = [int(a) for a in np.random.default_rng(3).integers(0, 6, size=300)]

    def observations(render: bool) -> np.ndarray:
        env = make_env(STAY_UP, backend="direct", seed=0, render_mode="rgb_array" if render else None)
        try:
            seen = [env.reset(seed=0)[0]]
            for action in actions:
                seen.append(env.step(action)[0])
                if render:
                    env.render()
        finally:
            env.close()
        return np.array(seen)
    assert np.array_equal(observations(render=True), observations(render=False))


@pytest.mark.parametrize("task", [CUBE, STAY_UP, HOP], ids=lambda task: task.env_id)
def test_render_fps_is_one_frame_per_step_and_the_size_is_the_callers(task):
    env = make_env(task, backend="direct", render_mode="rgb_array", render_width=160, render_height=90)
    try:
        env.reset(seed=0)
        assert env.metadata["render_modes"] == ["rgb_array", "human"]
        assert env.metadata["render_fps"] == pytest.approx(1.0 / task.default_params().running_step)
        frame = env.render()
        assert frame.shape == (90, 160, 3) and frame.dtype == np.uint8
    finally:
        env.close()


@pytest.mark.filterwarnings("ignore:.*not in the possible render_modes")  # gymnasium.make's, before ours
def test_bad_render_arguments_get_one_clear_error():
    with pytest.raises(ValueError, match="render_mode must be one of"):
        make_env(CUBE, backend="direct", render_mode="rgb")
    with pytest.raises(ValueError, match="render_width and render_height must be positive whole pixels"):
        make_env(CUBE, backend="direct", render_mode="rgb_array", render_width=0)
    env = make_env(CUBE, backend="direct")
    try:
        env.reset(seed=0)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert env.render() is None
        assert any("without a render_mode" in str(w.message) for w in caught)
        with pytest.raises(ValueError, match="image size must be whole pixels from 1 to 4096"):
            env.unwrapped.backend.render(5000, 10)
    finally:
        env.close()


def test_camera_config_defaults_and_errors(cube_params):
    cube = parse_robot_config(cube_params).camera
    assert (cube.distance, cube.yaw, cube.pitch, cube.z_offset) == (1.0, 90.0, -20.0, 0.0)
    del cube_params["camera"]
    assert parse_robot_config(cube_params).camera.distance == 1.5
    cube_params["camera"] = {"distance": 1.0, "zoom": 2}
    with pytest.raises(ConfigError, match=r"parameter ~/camera has unknown keys \['zoom'\]"):
        parse_robot_config(cube_params)
    cube_params["camera"] = {"distance": 0.0}
    with pytest.raises(ConfigError, match="parameter ~/camera/distance must be > 0"):
        parse_robot_config(cube_params)


@pytest.mark.parametrize("render_fps, every", [(1 / 0.06, 1), (30.0, 1), (31.0, 2), (1000.0, 34)])
def test_frame_every_keeps_videos_at_most_30_frames_per_second(render_fps, every):
    assert frame_every(render_fps) == every
    assert render_fps / every <= 30.0 + 1e-9


@pytest.mark.parametrize("task, horizon", [(CUBE, 15), (STAY_UP, 100)], ids=["cube", "monoped"])
def test_a_three_episode_video_is_a_valid_mp4_with_the_expected_frame_count(task, horizon, tmp_path):
    path = tmp_path / "episodes.mp4"
    env = make_env(task, backend="direct", seed=0, max_episode_steps=horizon, render_mode="rgb_array")
    recorder = VideoRecorder(env, path, episodes=3)
    rng = np.random.default_rng(0)
    lengths = []
    try:
        first_frame = None
        for _ in range(4):  # the fourth episode is not recorded
            recorder.reset(seed=0)
            first_frame = env.render() if first_frame is None else first_frame
            steps, done = 0, False
            while not done:
                _, _, terminated, truncated, _ = recorder.step(int(rng.integers(env.action_space.n)))
                steps, done = steps + 1, terminated or truncated
            lengths.append(steps)
    finally:
        recorder.close()
    every = frame_every(env.metadata["render_fps"])
    expected = sum(1 + steps // every for steps in lengths[:3])
    assert recorder.frames == expected and recorder.episodes_recorded == 3

    result = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(path), "-f", "null", "-"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and result.stderr == "", f"ffmpeg cannot decode {path}: {result.stderr}"
    with imageio.get_reader(path, format="FFMPEG") as reader:
        assert reader.get_meta_data()["fps"] == pytest.approx(env.metadata["render_fps"] / every, rel=1e-3)
        frames = [frame for frame in reader]
    assert len(frames) == expected
    assert frames[0].shape == (240, 320, 3)
    # H.264 is lossy: the decoded first frame is close to the rendered one, not equal.
    assert np.abs(frames[0].astype(int) - first_frame).mean() < 4.0


def test_a_video_needs_rgb_array_frames(tmp_path):
    env = make_env(CUBE, backend="direct")
    try:
        with pytest.raises(ValueError, match="render_mode='rgb_array'"):
            VideoRecorder(env, tmp_path / "x.mp4")
    finally:
        env.close()


class PeriodsPerStep(gymnasium.Env):
    """An env whose every step runs `periods` control periods of 1 ms (as the monoped's hop-level task does)."""

    multi_period_steps = True
    metadata = {"render_modes": ["rgb_array"], "render_fps": 1000.0}
    observation_space = gymnasium.spaces.Box(0.0, 1.0, (1,))
    action_space = gymnasium.spaces.Discrete(2)

    def __init__(self, periods):
        self.periods, self.period_hooks, self.render_mode = periods, [], "rgb_array"

    def reset(self, *, seed=None, options=None):
        return np.zeros(1, np.float32), {}

    def step(self, action):
        for _ in range(self.periods):
            for hook in self.period_hooks:
                hook()
        return np.zeros(1, np.float32), 0.0, False, False, {}

    def render(self):
        return np.zeros((24, 32, 3), np.uint8)


def test_an_env_whose_steps_run_many_periods_is_recorded_by_its_periods(tmp_path):
    env = PeriodsPerStep(periods=100)
    recorder = VideoRecorder(env, tmp_path / "hops.mp4")
    recorder.reset()
    for _ in range(3):
        recorder.step(0)
    env.step(0)  # a step not through the recorder (evaluate.py's random policy on the same env) is not recorded
    recorder.close()
    every = frame_every(1000.0)
    assert recorder.fps == pytest.approx(1000.0 / every) and recorder.fps <= 30.0
    assert recorder.frames == 1 + 300 // every, "frames in real time within the steps, not one per step"


def test_a_slow_motion_video_takes_k_times_the_frames_and_plays_k_times_longer(tmp_path):
    env = PeriodsPerStep(periods=100)
    recorder = VideoRecorder(env, tmp_path / "slow.mp4", slow_motion=4)
    recorder.reset()
    for _ in range(3):
        recorder.step(0)
    recorder.close()
    every = frame_every(1000.0 / 4)
    assert every == 9 and recorder.fps == pytest.approx(1000.0 / 9 / 4) and recorder.fps <= 30.0
    assert recorder.frames == 1 + 300 // every
    seconds = recorder.frames / recorder.fps  # of video, for 0.3 s of sim time
    assert seconds == pytest.approx(4 * (recorder.frames * every / 1000.0))
    with imageio.get_reader(tmp_path / "slow.mp4", format="FFMPEG") as reader:
        assert reader.get_meta_data()["fps"] == pytest.approx(recorder.fps, rel=1e-3)
    for bad in (0.5, float("nan"), 1000.0):
        with pytest.raises(ValueError, match="slow_motion must be a number from 1"):
            VideoRecorder(PeriodsPerStep(periods=1), tmp_path / "bad.mp4", slow_motion=bad)
