"""The run's plots: the learning curve (learning_curve.png) and the moving average it and the live plot draw."""
from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np

MOVING_AVERAGE = 50


def moving_average(values: Sequence[float], window: int = MOVING_AVERAGE) -> np.ndarray:
    """Mean of each run of `window` values (fewer at the start: the mean of those so far)."""
    sums = np.cumsum(np.asarray(values, dtype=float))
    counts = np.minimum(np.arange(1, len(sums) + 1), window)
    sums[window:] = sums[window:] - sums[:-window]
    return sums / counts


def learning_curve_png(episodes: Sequence[int], panels: Sequence[tuple[str, Sequence[float]]], title: str) -> bytes:
    """A PNG of one panel per (label, values by episode), each but epsilon's with its moving average over
    MOVING_AVERAGE episodes, titled `title`."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(panels), 1, figsize=(8, 2.2 + 2.0 * len(panels)), sharex=True)
    try:
        x = np.array(episodes)
        for ax, (label, values) in zip(axes, panels):
            if len(episodes):
                ax.plot(x, values, ".", alpha=0.4, markersize=3, label=label)
                if label != "epsilon":
                    ax.plot(x, moving_average(values), "-", label=f"moving average ({MOVING_AVERAGE})")
                    ax.legend(loc="best", fontsize="small")
            else:
                ax.text(0.5, 0.5, "no episodes yet", ha="center", va="center", transform=ax.transAxes)
            ax.set_ylabel(label)
            ax.grid(True, alpha=0.3)
        axes[-1].set_xlabel("episode")
        axes[0].set_title(title)
        fig.tight_layout()
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=100)
    finally:
        plt.close(fig)
    return buf.getvalue()
