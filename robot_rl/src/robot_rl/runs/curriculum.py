"""The attitude assist's curriculum: the scale of the sim's upright-pulling torque, taken away as fast as the
agent keeps up (params attitude_assist; pybullet_sim's World.set_attitude_assist).

The run starts at `scale`. With adapt_every N > 0, after every N episodes that ended, the scale is lowered
(x factor; under floor it becomes 0) when at most lower_at_most of them fell, and raised (/ factor, at most 1)
when raise_at_least or more did; an episode fell when the task terminated it (a truncation is no fall). The
scale and the outcomes of the window under way are part of the run's TrainingState, so a resumed run goes on
where its checkpoint left the curriculum. Pure: the trainer hands the scale to its env (RobotEnv's
set_assist_scale).

With free_share > 0, that share of the episodes trains with no assist at all, whatever the scale: the robot the
targets judge stays in the data at every stage. Which episodes are free follows from their number alone (spread
evenly: the fractional part of number x the golden ratio under free_share), so a resumed run draws the same. While
the scale is above 0 a free episode does not count in the window: the scale follows the assisted episodes.
"""
from __future__ import annotations

import math

from ..params import AttitudeAssist

GOLDEN_RATIO_FRACTION = (math.sqrt(5.0) - 1.0) / 2.0  # n x this mod 1 spreads any share of n evenly


def free_episode(episode: int, free_share: float) -> bool:
    """Whether a run's episode number `episode` (1: its first) trains without the assist, at free_share."""
    return (episode * GOLDEN_RATIO_FRACTION) % 1.0 < free_share


def needs_the_env_in_process(assist: AttitudeAssist) -> str:
    """Why a run whose assist adapts cannot train without a setter for it (its envs in other processes)."""
    return (f"attitude_assist/adapt_every ({assist.adapt_every}) changes the sim's assist during the run, which needs "
            f"the one env in the trainer's process: envs:=1 and an agent other than rllib_ppo, or adapt_every 0")


class AssistCurriculum:
    """The scale of `assist` (its params), adapted from the episodes' outcomes; `scale` and `window` (1: the
    episode fell) are what a checkpoint keeps."""

    def __init__(self, assist: AttitudeAssist, scale: float | None = None, window: list[int] | None = None):
        self.assist = assist
        self.scale = assist.scale if scale is None else scale
        self.window = list(window or [])
        self.last_falls = 0  # the falls of the last window that ended
        if not (0.0 <= self.scale <= 1.0) or not all(outcome in (0, 1) for outcome in self.window) \
                or len(self.window) >= max(assist.adapt_every, 1):
            raise ValueError(f"the attitude assist's state (scale {scale!r}, window {window!r}) does not fit "
                             f"its params (adapt_every {assist.adapt_every})")

    def free(self, episode: int) -> bool:
        """Whether the run's episode number `episode` (1: its first) trains without the assist."""
        return free_episode(episode, self.assist.free_share)

    def scale_of(self, episode: int) -> float:
        """The scale episode number `episode` trains with: 0 if it is free, else the curriculum's."""
        return 0.0 if self.free(episode) else self.scale

    def episode_ended(self, episode: int, fell: bool) -> bool:
        """Count the run's episode number `episode`, which ended (`fell`: terminated); True when the scale changed."""
        assist = self.assist
        if not assist.adapt_every or (self.free(episode) and self.scale > 0.0):
            return False
        self.window.append(int(fell))
        if len(self.window) < assist.adapt_every:
            return False
        falls, self.window = sum(self.window), []
        self.last_falls = falls
        if falls <= assist.lower_at_most:
            lowered = self.scale * assist.factor
            scale = 0.0 if lowered < assist.floor else lowered
        elif falls >= assist.raise_at_least:
            scale = min(1.0, max(self.scale, assist.floor) / assist.factor)
        else:
            return False
        scale = round(scale, 6)
        changed, self.scale = scale != self.scale, scale
        return changed
