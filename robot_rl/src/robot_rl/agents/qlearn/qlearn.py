"""Tabular Q-learning with the semantics of The Construct tutorials' qlearn.py (Victor Mayoral).

Differences from the tutorial:
- every random draw comes from the instance's own ``random.Random(seed)``, never the global module;
- ``learn(..., terminal=True)`` uses the reward alone as target: the tutorial bootstrapped from
  the Q-values of the terminal state, which never get updated and so only add noise;
- the table, hyper-parameters and RNG state go to JSON (no pickle) and reload exactly (to_dict/from_dict);
- three choices, each with the tutorial's rule as its default:
  exploration "noise" (the tutorial's: with probability epsilon, noise of +/- half the largest |Q| on
  every Q-value, so an untried action, Q = q_init, can never beat a tried one whose Q is above it)
  or "epsilon_greedy" (with probability epsilon, a uniformly random action);
  q_init, the value of a pair never updated (0);
  first_visit "reward" (the tutorial's: a pair's first update stores the reward) or "target" (a
  normal alpha step from q_init, which keeps an optimistic q_init optimistic for a while);
  step_size "constant" (the tutorial's: every update steps alpha) or "visits" (a pair's n-th update
  steps max(alpha, 1 / (n + 1)): Q is the mean of q_init and the pair's targets until that step comes
  down to alpha, so the values of pairs visited often stop following the last few noisy targets).
"""
from __future__ import annotations

import random
from collections.abc import Iterable
from typing import Any, Literal, overload

FORMAT = "robot_rl.qlearn/1"
EXPLORATIONS = ("noise", "epsilon_greedy")
FIRST_VISITS = ("reward", "target")
STEP_SIZES = ("constant", "visits")


def _to_lists(value: Any) -> Any:
    if isinstance(value, tuple):
        return [_to_lists(v) for v in value]
    return value


def _to_tuples(value: Any) -> Any:
    if isinstance(value, list):
        return tuple(_to_tuples(v) for v in value)
    return value


class QLearn:
    """Q-table keyed by (state, action) with epsilon exploration (see the module doc for the choices)."""

    def __init__(self, actions: Iterable[int], epsilon: float, alpha: float, gamma: float,
                 seed: int | None = None, exploration: str = "noise", q_init: float = 0.0,
                 first_visit: str = "reward", step_size: str = "constant") -> None:
        if exploration not in EXPLORATIONS or first_visit not in FIRST_VISITS or step_size not in STEP_SIZES:
            raise ValueError(f"exploration must be one of {EXPLORATIONS}, first_visit one of {FIRST_VISITS} and "
                             f"step_size one of {STEP_SIZES}, got {exploration!r}, {first_visit!r} and {step_size!r}")
        self.q: dict[tuple[str, int], float] = {}
        self.visits: dict[tuple[str, int], int] = {}  # updates per pair (kept with step_size "visits")
        self.epsilon = epsilon  # exploration probability
        self.alpha = alpha      # learning rate
        self.gamma = gamma      # discount factor
        self.actions = [int(a) for a in actions]
        self.rng = random.Random(seed)
        self.exploration, self.q_init, self.first_visit = exploration, q_init, first_visit
        self.step_size = step_size

    def getQ(self, state: str, action: int) -> float:
        return self.q.get((state, action), self.q_init)

    def learnQ(self, state: str, action: int, reward: float, value: float) -> None:
        """Move Q towards `value`; with first_visit "reward" a pair's first update stores `reward` itself."""
        pair = (state, action)
        step = self.alpha
        if self.step_size == "visits":
            n = self.visits.get(pair, 0) + 1
            self.visits[pair] = n
            step = max(self.alpha, 1.0 / (n + 1))
        old = self.q.get(pair)
        if old is None:
            if self.first_visit == "reward":
                self.q[pair] = reward
                return
            old = self.q_init
        self.q[pair] = old + step * (value - old)

    def learn(self, state1: str, action1: int, reward: float, state2: str,
              terminal: bool = False) -> None:
        """One Q-learning update; with `terminal` the target is the reward (no bootstrap)."""
        if terminal:
            target = reward
        else:
            maxqnew = max(self.getQ(state2, a) for a in self.actions)
            target = reward + self.gamma * maxqnew
        self.learnQ(state1, action1, reward, target)

    def _pick(self, q: list[float]) -> int:
        """Index of the maximum of `q`, ties broken at random."""
        maxQ = max(q)
        if q.count(maxQ) > 1:
            return self.rng.choice([i for i in range(len(self.actions)) if q[i] == maxQ])
        return q.index(maxQ)

    @overload
    def chooseAction(self, state: str, return_q: Literal[False] = False) -> int: ...

    @overload
    def chooseAction(self, state: str, return_q: Literal[True]) -> tuple[int, list[float]]: ...

    def chooseAction(self, state: str, return_q: bool = False) -> int | tuple[int, list[float]]:
        """Epsilon-noise action choice; returns (action, q) when `return_q`."""
        q = [self.getQ(state, a) for a in self.actions]
        maxQ = max(q)
        if self.exploration == "epsilon_greedy":
            action = self.rng.choice(self.actions) if self.rng.random() < self.epsilon else self.actions[self._pick(q)]
            return (action, q) if return_q else action
        if self.rng.random() < self.epsilon:
            mag = max(abs(min(q)), abs(maxQ))
            q = [q[i] + self.rng.random() * mag - .5 * mag for i in range(len(self.actions))]
        action = self.actions[self._pick(q)]
        if return_q:
            return action, q
        return action

    def greedy_action(self, state: str) -> int:
        """Best known action, no exploration (for evaluation)."""
        return self.actions[self._pick([self.getQ(state, a) for a in self.actions])]

    def to_dict(self) -> dict[str, Any]:
        """JSON-able snapshot of table, hyper-parameters and RNG state."""
        for state, _ in self.q:
            if not isinstance(state, str):
                raise TypeError(f"Q-table state keys must be str to be saved, got {state!r}")
        return {
            "format": FORMAT,
            "actions": list(self.actions),
            "alpha": self.alpha,
            "gamma": self.gamma,
            "epsilon": self.epsilon,
            "exploration": self.exploration,
            "q_init": self.q_init,
            "first_visit": self.first_visit,
            "step_size": self.step_size,
            "q": [[s, int(a), float(v)] for (s, a), v in sorted(self.q.items())],
            "visits": [[s, int(a), int(n)] for (s, a), n in sorted(self.visits.items())],
            "rng_state": _to_lists(self.rng.getstate()),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> QLearn:
        """Inverse of to_dict(); raises ValueError on a foreign or unknown format."""
        fmt = d.get("format") if isinstance(d, dict) else None
        if fmt != FORMAT:
            raise ValueError(f"not a QLearn table: format is {fmt!r}, expected {FORMAT!r}")
        ql = cls(d["actions"], d["epsilon"], d["alpha"], d["gamma"], exploration=d.get("exploration", "noise"),
                 q_init=d.get("q_init", 0.0), first_visit=d.get("first_visit", "reward"),
                 step_size=d.get("step_size", "constant"))
        ql.q = {(str(s), int(a)): float(v) for s, a, v in d["q"]}
        ql.visits = {(str(s), int(a)): int(n) for s, a, n in d.get("visits", [])}
        ql.rng.setstate(_to_tuples(d["rng_state"]))
        return ql
