"""Pushes: the base kicked horizontally at seeded random times, in training (the params' push_speed) and in
evaluation (evaluate.py --push V sets it), one implementation for both.

A push adds push_speed m/s of horizontal velocity to the robot's base in a random direction of the world's xy
plane, its pose and joints as they are (Backend.kick: the direct backend through its World, over ROS through the
sim's /gazebo/get_model_state and set_model_state). The gaps between pushes are uniform in push_interval (1-3 s of
sim time by default: one every 2 s on average), the first gap counted from the episode's start. The times and
directions of an episode are drawn from (seed, episode) alone (push_schedule): `seed` is that of the env's last
seeded reset, `episode` the number of resets since it (0 for the seeded one). evaluate.py resets once with the
evaluation seed, then every episode without one: its episodes 1, 2, ... get the same pushes on either backend and
for every policy; a training run (its first reset seeded with the run's seed) gets pushes of its own.
The env kicks before the control period in which a push's time falls, so a task whose step runs many control
periods (one step a hop) is pushed mid-step, at the time drawn, not at its next step.
"""
from __future__ import annotations

import math
from collections.abc import Iterator
from itertools import takewhile

import numpy as np

PUSH_GAP_S = (1.0, 3.0)  # s of sim time between two pushes, drawn uniformly (one every 2 s on average): the default


def push_times(seed: int, episode: int, gap: tuple[float, float] = PUSH_GAP_S) -> Iterator[tuple[float, float]]:
    """The pushes of an episode without end: (sim seconds after its start, heading in rad of the world xy plane),
    the gaps uniform in `gap`, drawn from (seed, episode) alone."""
    rng = np.random.default_rng([seed, episode])
    t = 0.0
    while True:
        t += float(rng.uniform(*gap))
        yield t, float(rng.uniform(-np.pi, np.pi))


def push_schedule(seed: int, episode: int, horizon_s: float,
                  gap: tuple[float, float] = PUSH_GAP_S) -> list[tuple[float, float]]:
    """The pushes of an episode of `horizon_s` sim seconds (push_times before it): the same arguments, the same
    pushes."""
    return list(takewhile(lambda push: push[0] < horizon_s, push_times(seed, episode, gap)))


class PushPlan:
    """An env's pushes: `start_episode` at every reset, then `due(stamp)` before every control period gives the
    velocity changes (m/s, world x and y) whose time has come."""

    def __init__(self, speed: float, gap: tuple[float, float] = PUSH_GAP_S):
        self.speed, self.gap = speed, gap
        self.seed, self.episode = 0, -1
        self.start = 0.0
        self._next: tuple[float, float] | None = None
        self._times: Iterator[tuple[float, float]] = iter(())

    def start_episode(self, stamp: float, seed: int | None) -> None:
        """A reset at sim time `stamp`, seeded with `seed` (None: the episode after the last one)."""
        if seed is not None:
            self.seed, self.episode = seed, 0
        else:
            self.episode += 1
        self.start = stamp
        self._times = push_times(self.seed, self.episode, self.gap)
        self._next = next(self._times) if self.speed > 0.0 else None

    def due(self, stamp: float) -> list[tuple[float, float]]:
        """The kicks to apply now, at sim time `stamp` (none while push_speed is 0)."""
        kicks = []
        while self._next is not None and stamp - self.start >= self._next[0]:
            heading = self._next[1]
            kicks.append((self.speed * math.cos(heading), self.speed * math.sin(heading)))
            self._next = next(self._times)
        return kicks
