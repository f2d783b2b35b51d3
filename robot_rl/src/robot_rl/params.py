"""Typed task parameters: frozen dataclasses built and validated from rosparam / YAML mappings.

A task declares its parameters as a frozen, keyword-only dataclass whose fields carry their range
(`param(low=..., high=...)`); nested dataclasses hold nested keys (`init_cube_pose: Point` reads
`init_cube_pose/x, y, z`). `Params.from_mapping(values, source)` checks every field and raises a
ParamError whose message is one line starting with `source` (usually the YAML file) and naming
the key. Keys the dataclass does not declare are ignored on the parameter server (the hopper's
parameters live at the root namespace, next to everything else there), and refused in a config file
(`strict=True`: a typo is never silently a default), but for the ones a params type declares in its
`TOLERATED_KEYS` (the tutorials' unused keys, kept in our YAML files as the tutorials wrote them).
"""
from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, field
from typing import Any, ClassVar, TypeVar

import yaml

from robot_rl.atomic import StrPath

_MERGE_TAG = "tag:yaml.org,2002:merge"
MAX_SEED = 2**31 - 1          # a seed is a ROS param (XML-RPC's 32-bit int) and seeds numpy ([0, 2**32))
MAX_COUNT = 10**9             # episodes, steps per episode: beyond any run, and within a ROS param
MAX_HORIZON_S = 86400.0       # s of sim time: a day, beyond any episode
MAX_RUNNING_STEP_S = 100.0    # the sim's longest step (pybullet_sim Step.MAX_STEPS of its default 1 ms)
P = TypeVar("P", bound="Params")


class ParamError(Exception):
    """Invalid, missing or unreadable parameter; str() is one line starting with the source."""


@dataclass(frozen=True)
class Range:
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False

    def contains(self, value: float) -> bool:
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            return False
        return not (self.high is not None and (value >= self.high if self.high_open else value > self.high))

    def __str__(self) -> str:
        low = "-inf" if self.low is None else repr(self.low)
        high = "inf" if self.high is None else repr(self.high)
        return f"{'(' if self.low_open else '['}{low}, {high}{')' if self.high_open else ']'}"


def param(*, low: float | None = None, high: float | None = None, low_open: bool = False, high_open: bool = False,
          choices: tuple[str, ...] | None = None, default: Any = MISSING, doc: str = "") -> Any:
    """A dataclass field with its allowed range (numbers) or choices (strings) and a one-line doc."""
    metadata = {"range": Range(low, high, low_open, high_open), "choices": choices, "doc": doc}
    return field(default=default, metadata=metadata)


def _convert(kind: type, value: Any, key: str, source: str) -> Any:
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or (isinstance(value, bool) and kind is not bool):
        raise ParamError(f"{source}: parameter '{key}' expected {kind.__name__}, "
                         f"got {value!r} ({type(value).__name__})")
    if isinstance(value, float) and math.isnan(value):
        raise ParamError(f"{source}: parameter '{key}' is NaN")
    return value


def _build(cls: type[Any], values: Mapping[str, Any], source: str, prefix: str) -> Any:
    if not isinstance(values, Mapping):
        raise ParamError(f"{source}: parameter '{prefix.rstrip('/') or '/'}' must be a mapping, "
                         f"got {values!r} ({type(values).__name__})")
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for f in dataclasses.fields(cls):
        key = prefix + f.name
        if f.name not in values:
            if f.default is MISSING:
                raise ParamError(f"{source}: missing parameter '{key}'")
            continue
        kind = hints[f.name]
        if isinstance(kind, type) and dataclasses.is_dataclass(kind):
            kwargs[f.name] = _build(kind, values[f.name], source, key + "/")
            continue
        value = _convert(kind, values[f.name], key, source)
        value_range, choices = f.metadata.get("range"), f.metadata.get("choices")
        if kind in (int, float) and value_range is not None and not value_range.contains(value):
            raise ParamError(f"{source}: parameter '{key}' = {value!r} out of range {value_range}")
        if choices is not None and value not in choices:
            raise ParamError(f"{source}: parameter '{key}' = {value!r} is not one of {', '.join(choices)}")
        kwargs[f.name] = value
    return cls(**kwargs)


def _unknown_keys(cls: type[Any], values: Mapping[str, Any], prefix: str) -> list[str]:
    """The keys of `values` (nested ones as a/b) that `cls` neither declares nor tolerates."""
    hints = typing.get_type_hints(cls)
    fields = {f.name for f in dataclasses.fields(cls)}
    unknown = []
    for key, value in values.items():
        if key not in fields:
            if key not in getattr(cls, "TOLERATED_KEYS", ()):
                unknown.append(f"{prefix}{key}")
            continue
        kind = hints[key]
        if isinstance(kind, type) and dataclasses.is_dataclass(kind) and isinstance(value, Mapping):
            unknown.extend(_unknown_keys(kind, value, f"{prefix}{key}/"))
    return unknown


class Params:
    """Base of the parameter dataclasses (declare them @dataclass(frozen=True, kw_only=True))."""

    TOLERATED_KEYS: ClassVar[tuple[str, ...]] = ()  # keys a config file may hold that nothing reads

    @classmethod
    def from_mapping(cls: type[P], values: Mapping[str, Any], source: str, strict: bool = False) -> P:
        """Validate a nested mapping (as rosparam or YAML give it); ParamError names the key and `source`.
        `strict` (a config file): a key the dataclass does not declare (nor tolerate) is refused too."""
        params = _build(cls, values, source, "")
        unknown = _unknown_keys(cls, values, "") if strict else []
        if unknown:
            known = ", ".join(f.name for f in dataclasses.fields(cls))  # type: ignore[arg-type]
            raise ParamError(f"{source}: unknown parameter '{unknown[0]}'"
                             f"{f' (and {len(unknown) - 1} more)' if len(unknown) > 1 else ''} (known: {known})")
        params.check(source)
        return params

    def check(self, source: str) -> None:
        """Checks across fields; raise ParamError starting with `source`."""

    def to_mapping(self) -> dict[str, Any]:
        """The nested mapping from_mapping reads (what params.yaml of a run holds)."""
        return dataclasses.asdict(self)  # type: ignore[call-overload]

    def with_changes(self: P, source: str, **changes: Any) -> P:
        """A copy with some keys changed, validated again (errors name `source`)."""
        return type(self).from_mapping({**self.to_mapping(), **changes}, source)

    def require_saved(self, saved: Mapping[str, Any]) -> None:
        """ValueError unless `saved` (a checkpoint's agent_params, today's defaults filled in) reads as these params:
        a resume trains on with the params its run began with. The message names each key that differs."""
        try:
            there = type(self).from_mapping(saved, "agent_params")
        except ParamError as error:
            raise ValueError(str(error)) from None
        if there != self:
            here = self.to_mapping()
            differ = ", ".join(f"{key} {value!r} there, {here[key]!r} here"
                               for key, value in there.to_mapping().items() if value != here[key])
            raise ValueError(f"its agent params differ from this run's ({differ}): resume with the params the run "
                             "began with")


@dataclass(frozen=True, kw_only=True)
class DeepAgentParams(Params):
    """What every deep agent's params hold (SB3's `NetworkParams`, RLlib's `RllibPpoParams`): its MLP's shape,
    Adam's step size and the scale of the rewards it learns from."""

    hidden_layers: int = param(low=1, high=8, doc="hidden layers of the MLP (each of the policy's and the value's)")
    hidden_units: int = param(low=1, high=4096, doc="units per hidden layer")
    learning_rate: float = param(low=0.0, low_open=True, high=1.0, doc="Adam's step size")
    reward_scale: float = param(low=0.0, low_open=True, high=1e6, default=1.0,
                                doc="the agent learns from the task's rewards times this (the run's files keep "
                                    "the task's)")


@dataclass(frozen=True, kw_only=True)
class Point(Params):
    x: float
    y: float
    z: float


@dataclass(frozen=True, kw_only=True)
class PushInterval(Params):
    """The sim seconds between two pushes, drawn uniformly in [low, high] (robot_rl.envs.pushes)."""

    low: float = param(low=0.1, high=MAX_HORIZON_S, default=1.0)
    high: float = param(low=0.1, high=MAX_HORIZON_S, default=3.0)


@dataclass(frozen=True, kw_only=True)
class AttitudeAssist(Params):
    """The sim's attitude assist, a curriculum's help (pybullet_sim's World.set_attitude_assist): a torque that pulls
    the base upright, of gains scale x stiffness and scale x damping; with adapt_every > 0 the run adapts the scale
    to how often its episodes end by termination (a fall), as robot_rl.runs.curriculum says."""

    stiffness: float = param(low=0.0, high=1e4, default=0.0, doc="N m/rad of tilt at scale 1 (0 with damping 0: off)")
    damping: float = param(low=0.0, high=1e4, default=0.0, doc="N m s/rad of horizontal spin at scale 1")
    scale: float = param(low=0.0, high=1.0, default=1.0, doc="the scale the run starts with")
    adapt_every: int = param(low=0, high=MAX_COUNT, default=0,
                             doc="episodes between two changes of the scale (0: it stays)")
    lower_at_most: int = param(low=0, high=MAX_COUNT, default=5,
                               doc="lower the scale when at most this many of those episodes fell")
    raise_at_least: int = param(low=1, high=MAX_COUNT, default=15,
                                doc="raise it when at least this many fell")
    factor: float = param(low=0.0, low_open=True, high=1.0, high_open=True, default=0.7,
                          doc="lower: scale x factor; raise: scale / factor (at most 1)")
    floor: float = param(low=0.0, high=1.0, default=0.01, doc="a lowered scale under this becomes 0")
    free_share: float = param(low=0.0, high=1.0, high_open=True, default=0.0,
                              doc="the share of episodes trained with no assist whatever the scale, spread evenly "
                                  "(they do not count in the window while the scale is above 0)")

    @property
    def active(self) -> bool:
        return self.stiffness > 0.0 or self.damping > 0.0


@dataclass(frozen=True, kw_only=True)
class TableSelection(Params):
    """Tabular Q-learning's check of its greedy table during training (robot_rl.agents.qlearn.selection): every
    `every` episodes the table plays `episodes` greedy episodes from a reset seeded with `seed`, and the best one by
    the task's headline metric is kept as qtable_best.json beside qtable.json."""

    every: int = param(low=0, high=MAX_COUNT, default=0, doc="training episodes between two checks (0: no checks)")
    episodes: int = param(low=1, high=MAX_COUNT, default=20, doc="greedy episodes a check plays")
    seed: int = param(low=0, high=MAX_SEED, default=500,
                      doc="the checks' reset seed: the same episodes every check; take one that evaluation does not")


@dataclass(frozen=True, kw_only=True)
class TaskParams(Params):
    """What every task's YAML holds: the tutorials' Q-learning keys and the env step."""

    alpha: float = param(low=0.0, high=1.0, doc="learning rate")
    gamma: float = param(low=0.0, high=1.0, doc="discount factor")
    epsilon: float = param(low=0.0, high=1.0, doc="initial exploration probability")
    epsilon_discount: float = param(low=0.0, high=1.0, doc="epsilon *= this before every episode (while > 0.05)")
    nepisodes: int = param(low=1, high=MAX_COUNT, doc="episodes to train")
    nsteps: int = param(low=1, high=MAX_COUNT, doc="env steps per episode at most")
    running_step: float = param(low=0.0, low_open=True, high=MAX_RUNNING_STEP_S, doc="sim seconds per env step")
    seed: int = param(low=0, high=MAX_SEED, default=0, doc="seeds the Q-learning RNG (exploration, tie breaks)")
    epsilon_min: float = param(low=0.0, high=1.0, default=0.05,
                               doc="epsilon decays only while above this (the tutorial's 0.05)")
    exploration: str = param(choices=("noise", "epsilon_greedy"), default="noise",
                             doc="noise: the tutorial's noise on Q; epsilon_greedy: a random action")
    q_init: float = param(default=0.0, doc="Q of a pair never updated (the tutorial's 0)")
    first_visit: str = param(choices=("reward", "target"), default="reward",
                             doc="a pair's first update: store the reward (tutorial) or step from q_init")
    step_size: str = param(choices=("constant", "visits"), default="constant",
                           doc="constant: every update steps alpha (tutorial); visits: a pair's n-th update steps "
                               "max(alpha, 1/(n+1))")
    selection: TableSelection = param(default=TableSelection(),
                                      doc="tabular Q-learning only: check the greedy table every few episodes on "
                                          "seeded episodes and keep the best as qtable_best.json (off by default)")
    push_speed: float = param(low=0.0, high=10.0, default=0.0,
                              doc="m/s: the env kicks the base this much horizontally, in a random direction, at "
                                  "random times (robot_rl.envs.pushes; 0: never; evaluate.py --push sets it)")
    push_interval: PushInterval = param(default=PushInterval(), doc="s of sim time between two pushes: uniform in "
                                                                    "[low, high]")
    attitude_assist: AttitudeAssist = param(default=AttitudeAssist(),
                                            doc="a torque of the sim's that pulls the base upright, taken away as "
                                                "the run learns (robot_rl.runs.curriculum; off by default)")

    def check(self, source: str) -> None:
        if not self.push_interval.low <= self.push_interval.high:
            raise ParamError(f"{source}: parameter 'push_interval/low' ({self.push_interval.low}) must not be above "
                             f"'push_interval/high' ({self.push_interval.high})")
        assist = self.attitude_assist
        if assist.adapt_every and not assist.active:
            raise ParamError(f"{source}: parameter 'attitude_assist/adapt_every' ({assist.adapt_every}) adapts an "
                             f"assist that is off: give it a stiffness or a damping")
        if assist.free_share and not assist.adapt_every:
            raise ParamError(f"{source}: parameter 'attitude_assist/free_share' ({assist.free_share}) mixes episodes "
                             f"without the assist into a curriculum: it needs adapt_every > 0")
        if assist.adapt_every and not assist.lower_at_most < assist.raise_at_least <= assist.adapt_every:
            raise ParamError(f"{source}: parameter 'attitude_assist': lower_at_most ({assist.lower_at_most}) < "
                             f"raise_at_least ({assist.raise_at_least}) <= adapt_every ({assist.adapt_every}) "
                             f"must hold")


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader with YAML's own tags only, that rejects duplicate mapping keys instead of keeping the last.

    Debian's rosparam, once imported, adds !radians (evaluated with eval()) and !degrees to
    yaml.SafeLoader: this loader takes its constructors and implicit resolvers from PyYAML's base classes,
    which nothing registers on, so a config is only ever data."""

    yaml_constructors = dict(yaml.constructor.SafeConstructor.yaml_constructors)
    yaml_implicit_resolvers = {first: list(resolvers)
                               for first, resolvers in yaml.resolver.Resolver.yaml_implicit_resolvers.items()}
    path = ""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen = set()
        for key_node, _ in node.value:
            if key_node.tag == _MERGE_TAG:
                continue
            key = self.construct_object(key_node, deep=deep)
            try:
                duplicate = key in seen
            except TypeError:  # unhashable key: let SafeLoader report it
                continue
            if duplicate:
                raise ParamError(f"{self.path}: duplicate key '{key}' at line {key_node.start_mark.line + 1}")
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def parse_scalar(text: str) -> Any:
    """A launch argument's text as YAML types a scalar (as roslaunch types a param: "12" an int, "0.5" a float,
    "true" a bool), read with the strict loader (no tag is evaluated); `text` itself if it is not a scalar."""
    loader = _UniqueKeyLoader(text)
    try:
        value = loader.get_single_data()
    except (yaml.YAMLError, ParamError):
        return text
    finally:
        loader.dispose()
    return value if isinstance(value, (int, float, bool)) else text


def load_yaml_file(path: StrPath) -> dict[str, Any]:
    """Parse a YAML mapping with yaml.safe_load semantics, rejecting duplicate keys."""
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except FileNotFoundError:
        raise ParamError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ParamError(f"{path}: cannot read: {getattr(e, 'strerror', None) or e}") from None
    loader = _UniqueKeyLoader(text)
    loader.path = str(path)
    try:
        data = loader.get_single_data()
    except yaml.YAMLError as e:
        raise ParamError(f"{path}: invalid YAML: {' '.join(str(e).split())}") from None
    finally:
        loader.dispose()
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ParamError(f"{path}: top level must be a mapping, got {type(data).__name__}")
    return data
