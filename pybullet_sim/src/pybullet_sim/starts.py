"""Remembered starts: the end states of the first physics steps after a reset, replayed instead of stepped.

Every reset restores one saved state, and PyBullet is deterministic, so the first physics steps after
a reset end in the same state whenever they are taken with the same commands (the cube's landing
after each reset is the case that costs). A World keeps these end states in a StartMemory and tells
it of every change through one call, `changed(kind)`: a World method that changes anything is marked
with the kind of change it makes (pybullet_sim.world's `_changes`), so that no change can leave a
remembered start standing that no longer holds.

A start is remembered the second time it is seen (up to MAX_REMEMBERED_STARTS of them), and only when
nothing but commands changed between the reset and its steps, and nothing at all during them.
"""
from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

MAX_REMEMBERED_STARTS = 8  # end states of starts after a reset a World keeps
MAX_SEEN_STARTS = 256      # starts a World counts while it waits to see one a second time

End = TypeVar("End")


class Change(enum.Enum):
    """What a World method changed, as far as remembered starts are concerned."""

    RESET = "reset"            # back to the saved state: a start may follow
    COMMANDS = "commands"      # a controller's command or running state: part of a start's key
    STEPS = "steps"            # physics steps taken: a start being recorded may end here
    STATE = "state"            # the robot moved by hand: what follows is no start
    PHYSICS = "physics"        # gravity, time step, solver: no remembered start holds any more


@dataclass(frozen=True)
class StartKey:
    """The first steps after a reset: how many, and every controller's command, running state and memory."""

    steps: int
    controllers: tuple[tuple[float, bool, tuple[float, float]], ...]


class StartMemory(Generic[End]):
    """The starts a World has seen and the end states of those it remembers.

    `save` captures the World's state as an End (called when a recorded start ends), `discard`
    releases one; the World restores an End itself when `replay` hands it one."""

    def __init__(self, save: Callable[[], End], discard: Callable[[End], None], enabled: bool):
        self._save, self._discard = save, discard
        self._enabled = enabled
        self._ends: dict[StartKey, End] = {}
        self._seen: set[StartKey] = set()
        self._at_reset = False  # nothing but commands has changed since the last reset
        self._recording: tuple[StartKey, int] | None = None  # a start to remember when step_count reaches this

    @property
    def at_reset(self) -> bool:
        """Whether the next steps would be a start that replay() could look up."""
        return self._at_reset and self._enabled

    def replay(self, key: StartKey, step_count: int) -> End | None:
        """The end state of the start `key` if remembered; else None, and the start is counted as seen (and
        recorded when it ends, if seen before). Only at_reset; after it the World is no longer at a reset."""
        self._at_reset = False
        end = self._ends.get(key)
        if end is None:
            if key in self._seen and len(self._ends) < MAX_REMEMBERED_STARTS:
                self._recording = (key, step_count + key.steps)
            elif len(self._seen) >= MAX_SEEN_STARTS:
                self._seen.clear()
            self._seen.add(key)
        return end

    def changed(self, kind: Change, step_count: int) -> None:
        """The one way a World tells the memory what changed (`step_count`: its steps since the start)."""
        if kind is Change.RESET:
            self._at_reset = True
            self._recording = None
        elif kind is Change.COMMANDS:
            self._recording = None
        elif kind is Change.STEPS:
            self._at_reset = False
            recording = self._recording
            if recording is not None and step_count >= recording[1]:
                if step_count == recording[1]:
                    self._ends[recording[0]] = self._save()
                self._recording = None
        elif kind is Change.STATE:
            self._at_reset = False
            self._recording = None
        else:
            self.forget()

    def forget(self) -> None:
        """Drop every remembered and seen start."""
        for end in self._ends.values():
            self._discard(end)
        self._ends.clear()
        self._seen.clear()
        self._at_reset = False
        self._recording = None
