"""Q-learning state keys of the monoped, chosen by the params' `state_key`."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from robot_rl import Discretiser, StateKey

from .params import MonopedParams
from .robot import JOINTS, MONOPED

TUTORIAL_DIVISIONS = 10
# Decades: a fall grows about e-fold every 0.3 s from ~1e-8 rad, so the decade of the tilt (rate) is
# about how long there is until the fall (measured, see config/stay_up.yaml).
RATE_EDGES = [10.0 ** e for e in range(-6, 1)]    # rad/s, 1e-6 .. 1: 8 bins
TILT_EDGES = [10.0 ** e for e in range(-6, 0)]    # rad, 1e-6 .. 0.1: 7 bins
KNEE_EDGES = [-0.3, -0.02]                        # rad: bent, slightly bent, straight (the limit is 0)


class TutorialStateKey:
    """The tutorial's state string: each of the 8 first observations binned by numpy.linspace(min, max, 10).

    Ranges as in seed 001's MonopedState: distance +/-(max_height - min_height), roll and pitch
    +/-max_incl, yaw +/-2 pi, contact force [0, 2 desired_force], and the joints' URDF limits (haa and
    hfe [-1.6, 1.6], kfe [-1.6, 0])."""

    def __init__(self, params: MonopedParams):
        span, incl = params.max_height - params.min_height, params.max_incl
        joint_limits = MONOPED.joint_limits(JOINTS)
        self.discretiser = Discretiser(
            low=[-span, -incl, -incl, -2 * math.pi, 0.0, *(low for low, _ in joint_limits)],
            high=[span, incl, incl, 2 * math.pi, 2 * params.desired_force, *(high for _, high in joint_limits)],
            bins=TUTORIAL_DIVISIONS, indices=range(8))

    def key(self, observation: np.ndarray) -> str:
        return self.discretiser.key(observation)

    def to_dict(self) -> dict[str, Any]:
        return self.discretiser.to_dict()


class TiltStateKey:
    """What decides a fall: whether the base leans forward or backward (the sign of pitch), how far it
    leans (the largest of abs(roll) and abs(pitch), in decades) and how fast (the largest of the two tilt
    rates, in decades), the knee (bent, slightly bent, straight) and whether the foot touches the ground:
    2 x 7 x 8 x 3 x 2 = 672 keys. Values beyond the outer edges land in the edge bins. The sign of roll is
    left out: with it (1344 keys) 1000 episodes learned far less (docs/research/2026-11-25-monoped-actions.md)."""

    def __init__(self, params: MonopedParams):
        self.discretiser = Discretiser.from_edges([[0.0], TILT_EDGES, RATE_EDGES, KNEE_EDGES, [0.5]])

    def key(self, observation: np.ndarray) -> str:
        roll, pitch, force, kfe, roll_rate, pitch_rate = (float(observation[i]) for i in (1, 2, 4, 7, 8, 9))
        return self.discretiser.key([pitch, max(abs(roll), abs(pitch)), max(abs(roll_rate), abs(pitch_rate)),
                                     kfe, 1.0 if force > 0.0 else 0.0])

    def to_dict(self) -> dict[str, Any]:
        return {"format": "hopper_training.tilt_state_key/1", "discretiser": self.discretiser.to_dict()}


def monoped_state_key(params: MonopedParams) -> StateKey:
    """The key the params choose: "tilt" (TiltStateKey) or "tutorial" (TutorialStateKey)."""
    return TiltStateKey(params) if params.state_key == "tilt" else TutorialStateKey(params)
