"""Observation -> Q-table state key, by binning each used dimension as numpy.digitize does.

Replaces the tutorials' keys built by concatenating str(float) values, in which "-0.0" and "0.0"
were different states and nothing separated the numbers. Keys here are bin indices joined by "_".
"""
from __future__ import annotations

from bisect import bisect_right
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

FORMAT = "robot_rl.discretiser/1"


class Discretiser:
    """Per-dimension edges numpy.linspace(low[i], high[i], bins[i]) (or explicit, see from_edges);
    a dimension with n edges has bin indices 0..n."""

    def __init__(self, low: Sequence[float], high: Sequence[float], bins: int | Sequence[int],
                 indices: Sequence[int] | None = None) -> None:
        lows, highs = [float(v) for v in low], [float(v) for v in high]
        n = len(lows)
        if n == 0 or len(highs) != n:
            raise ValueError(f"low and high need the same non-zero length, got {n} and {len(highs)}")
        for i, (lo, hi) in enumerate(zip(lows, highs)):
            if not lo < hi:  # also rejects NaN
                raise ValueError(f"dimension {i}: need low < high, got low={lo}, high={hi}")
        bins_list = [bins] * n if isinstance(bins, (int, np.integer)) else list(bins)
        if len(bins_list) != n:
            raise ValueError(f"bins has {len(bins_list)} entries, expected {n} (one per dimension)")
        for i, b in enumerate(bins_list):
            if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or b < 2:
                raise ValueError(f"dimension {i}: bins must be an int >= 2, got {b!r}")
        self._use([np.linspace(lo, hi, int(b)) for lo, hi, b in zip(lows, highs, bins_list)], indices)

    def _use(self, edges: list[np.ndarray], indices: Sequence[int] | None) -> None:
        self.edges = edges
        self._edge_lists = [e.tolist() for e in edges]  # plain floats: bisect on them beats numpy.digitize per value
        self.indices = None if indices is None else [int(i) for i in indices]
        if self.indices is not None and len(self.indices) != len(edges):
            raise ValueError(f"indices has {len(self.indices)} entries, there are {len(edges)} dimensions")
        if self.indices is not None and min(self.indices) < 0:
            raise ValueError(f"indices must be >= 0, got {self.indices}")

    @classmethod
    def from_edges(cls, edges: Sequence[ArrayLike], indices: Sequence[int] | None = None) -> Discretiser:
        """Explicit, increasing bin edges per dimension (e.g. a dead band around 0; one edge: a sign)."""
        arrays = [np.asarray(e, dtype=float) for e in edges]
        for i, e in enumerate(arrays):
            if e.ndim != 1 or e.size < 1 or not np.all(np.diff(e) > 0) or not np.all(np.isfinite(e)):
                raise ValueError(f"dimension {i}: edges must be increasing finite numbers, got {e.tolist()}")
        discretiser = cls.__new__(cls)
        discretiser._use(arrays, indices)
        return discretiser

    def _select(self, obs: Any) -> list[float]:
        values = np.asarray(obs, dtype=float)
        dims: Sequence[int]
        if values.ndim != 1:
            raise ValueError(f"observation must be 1-D, got shape {values.shape}")
        if self.indices is None:
            if values.size != len(self.edges):
                raise ValueError(f"observation has {values.size} values, discretiser expects {len(self.edges)}")
            used, dims = values.tolist(), range(values.size)
        else:
            if max(self.indices) >= values.size:
                raise ValueError(f"observation has {values.size} values, indices {self.indices} need "
                                 f"at least {max(self.indices) + 1}")
            every = values.tolist()
            used, dims = [every[i] for i in self.indices], self.indices
        for dim, value in zip(dims, used):
            if value != value:
                raise ValueError(f"observation dimension {dim} is NaN")
        return used

    def digitise(self, obs: Any) -> tuple[int, ...]:
        """Bin index per used dimension: 0 below low, bins[i] at or above high (numpy.digitize's bins:
        edges[k - 1] <= value < edges[k] gives k)."""
        return tuple(map(bisect_right, self._edge_lists, self._select(obs)))

    def key(self, obs: Any) -> str:
        """State key such as "5_5_5_5_1_5_5_10"."""
        return "_".join(map(str, self.digitise(obs)))

    def to_dict(self) -> dict[str, Any]:
        return {"format": FORMAT, "edges": [e.tolist() for e in self.edges], "indices": self.indices}
