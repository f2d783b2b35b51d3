"""Validation of rosparam/YAML parameters with one-line errors a node can print before exiting.

Every ParamError message is a single line starting with the parameter source (usually a file path).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import yaml

from robot_rl.atomic import StrPath

_TYPES = (float, int, bool, str, dict)
_MERGE_TAG = "tag:yaml.org,2002:merge"


class ParamError(Exception):
    """Invalid, missing or unreadable parameter; str() is one line starting with the source."""


@dataclass(frozen=True)
class Param:
    key: str
    type: type
    low: float | None = None
    high: float | None = None
    low_inclusive: bool = True
    high_inclusive: bool = True
    doc: str = ""

    def __post_init__(self) -> None:
        if self.type not in _TYPES:
            raise ValueError(f"Param '{self.key}': type must be one of float, int, bool, str, dict")
        if (self.low is not None or self.high is not None) and self.type not in (float, int):
            raise ValueError(f"Param '{self.key}': a range needs type float or int")

    def range_text(self) -> str:
        """The allowed range in interval notation, e.g. "(0.0, 1.0]"."""
        lo = "-inf" if self.low is None else repr(self.low)
        hi = "inf" if self.high is None else repr(self.high)
        return (f"{'[' if self.low_inclusive else '('}{lo}, {hi}"
                f"{']' if self.high_inclusive else ')'}")


def _convert(p: Param, value: Any, source: str) -> Any:
    ok = isinstance(value, p.type) and not (isinstance(value, bool) and p.type is not bool)
    if p.type is float and isinstance(value, int) and not isinstance(value, bool):
        value, ok = float(value), True
    if not ok:
        raise ParamError(f"{source}: parameter '{p.key}' expected {p.type.__name__}, "
                         f"got {value!r} ({type(value).__name__})")
    if p.type is float and math.isnan(value):
        raise ParamError(f"{source}: parameter '{p.key}' is NaN")
    if p.type is dict:
        return dict(value)
    return value


def _in_range(p: Param, value: float) -> bool:
    if p.low is not None and (value < p.low if p.low_inclusive else value <= p.low):
        return False
    if p.high is not None and (value > p.high if p.high_inclusive else value >= p.high):
        return False
    return True


def _unflatten(values: dict[str, Any], key: str) -> dict[str, Any] | None:
    """Rebuild the dict under `key` from flattened "key/..." entries, or None if there are none."""
    prefix = key + "/"
    sub = {k[len(prefix):]: v for k, v in values.items() if k.startswith(prefix)}
    if not sub:
        return None
    nested: dict[str, Any] = {}
    for path, v in sub.items():
        *parents, leaf = path.split("/")
        node = nested
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = v
    return nested


def validate(values: dict[str, Any], spec: list[Param], source: str) -> dict[str, Any]:
    """Check `values` (flat, "/"-separated keys) against `spec`.

    Returns a copy of `values` with the specified entries converted (int -> float where float is
    expected). A dict-typed Param also accepts its flattened form ("key/sub" entries).
    """
    out = dict(values)
    for p in spec:
        if p.key in values:
            value = values[p.key]
        elif p.type is dict and (nested := _unflatten(values, p.key)) is not None:
            value = nested
        else:
            raise ParamError(f"{source}: missing parameter '{p.key}'")
        value = _convert(p, value, source)
        if p.type in (float, int) and not _in_range(p, value):
            raise ParamError(f"{source}: parameter '{p.key}' = {value!r} out of range {p.range_text()}")
        out[p.key] = value
    return out


def flatten(nested: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """{"a": {"b": 1}} -> {"a/b": 1}; empty dicts stay as leaves."""
    flat: dict[str, Any] = {}
    for k, v in nested.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and v:
            flat.update(flatten(v, key + "/"))
        else:
            flat[key] = v
    return flat


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that rejects duplicate mapping keys instead of keeping the last one."""

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


def load_yaml_file(path: StrPath) -> dict[str, Any]:
    """Parse a YAML mapping with yaml.safe_load semantics, rejecting duplicate keys."""
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except FileNotFoundError:
        raise ParamError(f"{path}: no such file") from None
    except OSError as e:
        raise ParamError(f"{path}: cannot read: {e.strerror}") from None
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
