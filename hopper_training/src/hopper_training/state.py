"""Q-learning state keys of the monoped."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from robot_rl.discretiser import Discretiser

from .params import MonopedParams

TUTORIAL_DIVISIONS = 10


class TutorialStateKey:
    """The tutorial's state string: each of the 8 observations binned by numpy.linspace(min, max, 10).

    Ranges as in seed 001's MonopedState: distance +/-(max_height - min_height), roll and pitch
    +/-max_incl, yaw +/-2 pi, contact force [0, 2 desired_force], haa and hfe [-1.6, 1.6], kfe [-1.6, 0]."""

    def __init__(self, params: MonopedParams):
        span, incl = params.max_height - params.min_height, params.max_incl
        self.discretiser = Discretiser(
            low=[-span, -incl, -incl, -2 * math.pi, 0.0, -1.6, -1.6, -1.6],
            high=[span, incl, incl, 2 * math.pi, 2 * params.desired_force, 1.6, 1.6, 0.0],
            bins=TUTORIAL_DIVISIONS)

    def key(self, observation: np.ndarray) -> str:
        return self.discretiser.key(observation)

    def to_dict(self) -> dict[str, Any]:
        return self.discretiser.to_dict()
