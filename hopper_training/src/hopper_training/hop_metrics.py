"""How the monoped hopped in an episode, tracked from the per-step readings (the env feeds one sample a step).

Definitions (each step's readings are one sample, running_step apart):
- a flight is a run of consecutive samples without foot contact (contact: a contact force above 0, as the
  observation's) that follows a sample with contact and ends with one (the landing); a hop is a flight of
  at least MIN_FLIGHT_S, counted as samples x running_step (0.06 s: 3 samples at 20 ms, a rise of about
  4 mm), in which the base rises (its fitted arc starts upwards). Bounces and contact chatter shorter than
  that are not hops, nor is a foot that slips off the ground as the robot falls.
- apex_height: over the episode's hops, the mean of the base's highest point in each flight above its
  height at the start of the episode (m; 0 with no hop). The odometry's height has 0.01 m of noise, so the
  highest point is that of a ballistic arc (z = a + b t - g t^2 / 2) fitted by least squares to the
  flight's samples, not the highest sample (which the noise would raise by about 1.5 cm).
- forward_speed: the base's mean velocity along +x over the last FORWARD_WINDOW_S (5 s) of the episode,
  from its odometry positions (x now - x then) / 5 s; over the whole episode if it is shorter.
- lateral_drift: abs(y now - y at the start) of the base (m).
"""
from __future__ import annotations

from collections import deque

import numpy as np

MIN_FLIGHT_S = 0.06
FORWARD_WINDOW_S = 5.0
GRAVITY = 9.81  # m/s^2: the sim's default gravity


def fit_flight(times: list[float], heights: list[float]) -> tuple[float, float]:
    """(highest point within the flight, vertical velocity at its first sample) of the ballistic arc fitted to
    (time, height) samples of one flight."""
    t = np.asarray(times) - times[0]
    z = np.asarray(heights)
    design = np.column_stack([np.ones_like(t), t])
    (a, b), *_ = np.linalg.lstsq(design, z + 0.5 * GRAVITY * t * t, rcond=None)
    top = min(max(b / GRAVITY, 0.0), float(t[-1]))
    return float(a + b * top - 0.5 * GRAVITY * top * top), float(b)


class HopTracker:
    """Hops, apex height, forward speed and lateral drift of one episode, from samples fed in order."""

    def __init__(self, running_step: float):
        self.running_step = running_step
        self.reset(0.0, (0.0, 0.0, 0.0), True)

    def reset(self, time: float, position: tuple[float, ...], contact: bool) -> None:
        """Start an episode at its first sample."""
        self.start = tuple(position)
        self.hops = 0
        self.apexes: list[float] = []
        self._was_in_contact = contact   # a flight needs a contact before it
        self._flight: tuple[list[float], list[float]] | None = None
        self._x_history: deque[tuple[float, float]] = deque([(time, position[0])])
        self._last = (time, tuple(position))

    def add(self, time: float, position: tuple[float, ...], contact: bool) -> None:
        """One step's sample: sim time (s), base position (m, world frame), foot contact."""
        if not contact:
            if self._flight is not None:
                self._flight[0].append(time)
                self._flight[1].append(position[2])
            elif self._was_in_contact:
                self._flight = ([time], [position[2]])
        else:
            flight = self._flight
            if flight is not None and len(flight[0]) * self.running_step >= MIN_FLIGHT_S - 1e-9:
                apex, rising = fit_flight(*flight)
                if rising > 0.0:
                    self.hops += 1
                    self.apexes.append(apex - self.start[2])
            self._flight = None
        self._was_in_contact = contact
        history = self._x_history
        history.append((time, position[0]))
        while len(history) > 1 and history[1][0] <= time - FORWARD_WINDOW_S + 1e-9:
            history.popleft()
        self._last = (time, tuple(position))

    @property
    def apex_height(self) -> float:
        return float(np.mean(self.apexes)) if self.apexes else 0.0

    @property
    def forward_speed(self) -> float:
        (t0, x0), (t1, x1) = self._x_history[0], self._x_history[-1]
        return (x1 - x0) / (t1 - t0) if t1 > t0 else 0.0

    @property
    def lateral_drift(self) -> float:
        return abs(self._last[1][1] - self.start[1])

    def summary(self) -> dict[str, float]:
        """The episode's figures so far, as the env puts them in info."""
        return {"hops": self.hops, "apex_height": self.apex_height, "forward_speed": self.forward_speed,
                "lateral_drift": self.lateral_drift}
