"""Videos of episodes: a gymnasium wrapper that writes an env's rgb_array frames to an mp4 (H.264 through
imageio's ffmpeg plugin; imageio-ffmpeg ships the ffmpeg binary).

Like gymnasium's RecordVideo, it takes a frame after each reset and after steps, but it keeps the video
in real time at a frame rate a player handles: one frame every `frame_every` steps, the fewest that
keep render_fps / frame_every at most MAX_FPS. The cube (a step of 0.06 s of sim time) gets every step
at 16.7 frames/s; the monoped (20 ms steps, render_fps 50) every 2nd step at 25 frames/s. An
episode of n steps thus gives 1 + n // frame_every frames. An env whose step runs several control
periods (`multi_period_steps`: the monoped's hop-level task, a step a hop) is counted by its periods
instead, through its `period_hooks`, so its video is in real time too. `slow_motion` K plays it K times
slower than real time, with frames taken K times as often (still at most MAX_FPS a second of video): K = 4
shows a monoped's hop, a flight of about 0.2 s, in some 20 frames. Only the first `episodes` episodes after
the wrapper is made are recorded; the file is complete once the wrapper is closed.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

MAX_FPS = 30.0


def frame_every(render_fps: float, max_fps: float = MAX_FPS) -> int:
    """Steps per video frame: the fewest that keep the video at most `max_fps` frames per second."""
    return max(1, math.ceil(render_fps / max_fps - 1e-9))


class VideoRecorder(gymnasium.Wrapper[Any, Any, Any, Any]):
    """Records the first `episodes` episodes (all if None) of an env made with render_mode="rgb_array",
    `slow_motion` times slower than real time (1: real time)."""

    def __init__(self, env: gymnasium.Env[Any, Any], path: str | Path, episodes: int | None = None,
                 max_fps: float = MAX_FPS, slow_motion: float = 1.0):
        super().__init__(env)
        if env.render_mode != "rgb_array":
            raise ValueError(f"recording a video needs an env made with render_mode='rgb_array', not "
                             f"{env.render_mode!r}")
        if not (isinstance(slow_motion, (int, float)) and math.isfinite(slow_motion) and 1.0 <= slow_motion <= 100.0):
            raise ValueError(f"slow_motion must be a number from 1 (real time) to 100, got {slow_motion!r}")
        render_fps = float(env.metadata["render_fps"])
        self.path = Path(path)
        self.episodes = episodes
        self.slow_motion = float(slow_motion)
        self.frame_every = frame_every(render_fps / self.slow_motion, max_fps)
        self.fps = render_fps / self.frame_every / self.slow_motion  # frames per second of video
        self.frames = 0                  # written so far
        self.episodes_recorded = 0       # started while recording
        self._steps = 0                  # steps (or control periods) of the episode being recorded
        self._recording = False
        self._writer: Any = None
        self._by_periods = bool(getattr(env.unwrapped, "multi_period_steps", False))
        self._stepping = False           # inside this wrapper's step: periods of other callers' steps are not ours
        if self._by_periods:
            env.unwrapped.period_hooks.append(self._on_period)  # type: ignore[attr-defined]

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        result = super().reset(**kwargs)
        self._recording = self.episodes is None or self.episodes_recorded < self.episodes
        if self._recording:
            self.episodes_recorded += 1
            self._steps = 0
            self._write_frame()
        return result

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        self._stepping = True
        try:
            result = super().step(action)
        finally:
            self._stepping = False
        if not self._by_periods:
            self._count()
        return result  # type: ignore[return-value]  # the wrapped env's 5-tuple

    def _on_period(self) -> None:
        if self._stepping:
            self._count()

    def _count(self) -> None:
        """One more step (or control period): a frame every frame_every of them."""
        if self._recording:
            self._steps += 1
            if self._steps % self.frame_every == 0:
                self._write_frame()

    def _write_frame(self) -> None:
        frame: Any = self.env.render()
        if not (isinstance(frame, np.ndarray) and frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8):
            raise ValueError(f"render() must return an HxWx3 uint8 array, got {type(frame).__name__} "
                             f"{getattr(frame, 'shape', '')}")
        if self._writer is None:
            import imageio.v2 as imageio
            # macro_block_size=2: H.264 (yuv420p) needs even sides; any even size is written as it is.
            self._writer = imageio.get_writer(self.path, format="FFMPEG", mode="I", fps=self.fps, codec="libx264",
                                              pixelformat="yuv420p", macro_block_size=2, ffmpeg_log_level="error")
        self._writer.append_data(frame)
        self.frames += 1

    def close(self) -> None:
        """Finish the video file, then close the env."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        super().close()
