"""The trend chart of a laboratory's history (docs/domain.md §4.1): its En and its z (the one
that counts) per round, plain data in, a matplotlib figure (``history_figure``, the
participant report rasterises it) or SVG text (``history_chart``, the pages) out, drawn as
``analysis.charts`` draws (matplotlib's object-oriented API, byte-stable SVG)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from analysis.charts import BAD, LAB, OWN, _figure, _svg, _with_rc

#: z limits of ISO 13528:2022 9.4.2 (warning above 2, action from 3)
Z_WARNING, Z_ACTION = 2.0, 3.0
TITLE = "History: En and z per round"
#: "how to read this" under the chart (the pages and the participant report)
CAPTION = (
    "En and z (z′ where it counts) at every point, per round; the line joins the rounds' "
    "mean |score|; red: outside |En| ≤ 1, |z| ≤ 2."
)


@_with_rc
def history_figure(
    rounds: Sequence[str],
    en: Sequence[Sequence[float]],
    z: Sequence[Sequence[float]],
    *,
    en_limit: float = 1.0,
    title: str = TITLE,
) -> Figure:
    """One column per round (in order): the laboratory's En at each of its points above,
    its z (or z′) below, each with its limits; a line joins the rounds' mean |score|."""
    fig = _figure(5.6, 4.2)
    top, bottom = fig.subplots(2, 1, sharex=True)
    x = np.arange(len(rounds), dtype=float)
    _panel(top, x, en, (en_limit,), "En")
    _panel(bottom, x, z, (Z_WARNING, Z_ACTION), "z (or z′)")
    bottom.set_xticks(x, list(rounds), rotation=30 if len(rounds) > 4 else 0)
    bottom.set_xlabel("Round")
    top.set_title(title)
    return fig


def history_chart(
    rounds: Sequence[str],
    en: Sequence[Sequence[float]],
    z: Sequence[Sequence[float]],
    *,
    en_limit: float = 1.0,
    title: str = TITLE,
) -> str:
    """:func:`history_figure` as inline SVG (the history pages)."""
    return _svg(history_figure(rounds, en, z, en_limit=en_limit, title=title), label=title)


def _panel(ax, x: np.ndarray, values: Sequence[Sequence[float]], limits: tuple[float, ...],
           label: str) -> None:  # fmt: skip
    widest = max(limits)
    means = []
    for xi, found in zip(x, values, strict=True):
        v = np.asarray([f for f in found if f is not None], dtype=float)
        v = v[np.isfinite(v)]
        means.append(float(np.mean(np.abs(v))) if v.size else np.nan)
        if v.size:
            spread = np.linspace(-0.12, 0.12, v.size) if v.size > 1 else np.zeros(1)
            colours = [BAD if abs(s) > limits[0] else LAB for s in v]
            ax.scatter(xi + spread, v, s=9, c=colours, linewidths=0)
            widest = max(widest, float(np.max(np.abs(v))))
    ax.plot(x, means, color=OWN, lw=1.2, marker="D", ms=3, label="mean |score|")
    for limit in limits:
        for y in (limit, -limit):
            ax.axhline(y, color=BAD, lw=0.8, ls="--" if limit == limits[-1] else ":")
    ax.axhline(0, color="black", lw=0.6)
    ax.set_ylim(-1.1 * widest, 1.1 * widest)
    ax.set_xlim(-0.5, len(x) - 0.5)
    ax.set_ylabel(label)
