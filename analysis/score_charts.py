"""The score bars of the standard graphs of ISO 13528:2022 Clause 10 (docs/domain.md §11.4,
§11.5): each participant's z or En at one point, sorted, and one participant's En and z at
every point it measured.  Plain data in, a matplotlib ``Figure`` out (``*_figure``) or SVG
text (``*_chart``).

``analysis.standard_charts`` holds these with the other standard graphs (its ``CAPTIONS``
and ``FIGURES`` name them all); the helpers, colours and style are ``analysis.charts``'s.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from analysis.charts import BAD, LAB, MANY, OWN, WARN, _figure, _lab_ticks, _note, _runs, _with_rc
from analysis.charts import svg_of as _svg_of
from analysis.core import graphs

if TYPE_CHECKING:
    from matplotlib.axes import Axes


# --------------------------------------------------------------------------- helpers


def _bars(ax: Axes, x: np.ndarray, values: np.ndarray, colours: list[str], own: np.ndarray) -> None:
    """Bars up to ``MANY`` labs; beyond, one line collection (a bar is a line there)."""
    if len(x) <= MANY:
        ax.bar(x, values, color=colours, width=0.6)
        return
    ax.vlines(x, 0, values, colors=colours, lw=0.8)
    if own.any():  # the reader's own bar drawn again on top, wider
        ax.vlines(x[own], 0, values[own], colors=OWN, lw=2.5)


def z_colour(value: float) -> str:
    """The colour of a z bar: red at an action signal (|z| ≥ 3), amber at a warning."""
    return BAD if abs(value) >= 3 else WARN if abs(value) > 2 else LAB


def en_colour(value: float, limit: float) -> str:
    return BAD if abs(value) > limit else LAB


def _limits(ax: Axes, lines: Sequence[tuple[float, str]], values: np.ndarray, least: float) -> None:
    for y, colour in lines:
        ax.axhline(y, color=colour, lw=1, ls="--")
        ax.axhline(-y, color=colour, lw=1, ls="--")
    ax.axhline(0, color="black", lw=0.6)
    top = max(least, float(np.max(np.abs(values))) * 1.1 if values.size else 0.0)
    ax.set_ylim(-top, top)


# --------------------------------------------------------------------------- sorted bars


def _sorted_bars(
    labels: Sequence[str], scores: ArrayLike, *, title: str, name: str,
    highlight: str | None, colour: Callable[[float], str], lines: Sequence[tuple[float, str]],
    least: float,
) -> Figure:  # fmt: skip
    s = graphs.sorted_scores(list(labels), scores)
    if not s.labels:
        return _note(title, f"No {name} at this point.")
    fig = _figure(5.6, 3.0)
    ax = fig.add_subplot()
    x = np.arange(len(s.labels))
    own = np.array([lab == highlight for lab in s.labels], dtype=bool)
    colours = [OWN if o else colour(float(v)) for o, v in zip(own, s.values, strict=True)]
    _bars(ax, x, s.values, colours, own)
    _limits(ax, lines, s.values, least)
    ax.set_xlabel("Participant, sorted")
    _lab_ticks(ax, x, list(s.labels), highlight)
    if s.not_scored:
        ax.set_xlabel(f"{ax.get_xlabel()}; not scored: {len(s.not_scored)}")
    ax.set_ylabel(name)
    ax.set_title(title)
    return fig


@_with_rc
def z_figure(
    labels: Sequence[str], z: ArrayLike, *, title: str, name: str = "z",
    highlight: str | None = None,
) -> Figure:  # fmt: skip
    """z (or z′: ``name``) per lab sorted (``core.graphs.sorted_scores``), ±2 and ±3 lines;
    bars beyond 3 red, between 2 and 3 amber, the reader's own in ``OWN``."""
    return _sorted_bars(labels, z, title=title, name=name, highlight=highlight, colour=z_colour,
                        lines=((2.0, WARN), (3.0, BAD)), least=3.6)  # fmt: skip


@_with_rc
def en_bar_figure(
    labels: Sequence[str], en: ArrayLike, *, title: str, limit: float = 1.0,
    highlight: str | None = None,
) -> Figure:  # fmt: skip
    """Signed En per lab sorted, ±limit lines, bars outside red."""
    return _sorted_bars(labels, en, title=title, name="En", highlight=highlight,
                        colour=lambda v: en_colour(v, limit), lines=((limit, BAD),),
                        least=1.5 * limit)  # fmt: skip


z_chart = _svg_of(z_figure)
en_bar_chart = _svg_of(en_bar_figure)
# --------------------------------------------------------------------------- one lab


@_with_rc
def lab_overview_figure(
    points: Sequence[str], groups: Sequence[str], en: ArrayLike, z: ArrayLike,
    *, code: str, limit: float = 1.0, z_name: str = "z or z′",
) -> Figure:  # fmt: skip
    """One lab's En (top) and z (bottom) at each of its points, in the order given, grouped by
    ``groups`` (device · bench), with ±limit and ±2/±3 lines; NaN: not scored there."""
    title = f"{code}: En and {z_name} at every point"
    if not points:
        return _note(title, f"{code} has no scored result in this run.")
    n = len(points)
    fig = _figure(min(12.0, 4.0 + 0.09 * n), 4.6)
    top, bottom = fig.subplots(2, 1, sharex=True)
    x = np.arange(n)
    e, zz = np.asarray(en, dtype=float), np.asarray(z, dtype=float)
    for ax, v, colour, lines, least, name in (
        (top, e, lambda s: en_colour(s, limit), ((limit, BAD),), 1.5 * limit, "En"),
        (bottom, zz, z_colour, ((2.0, WARN), (3.0, BAD)), 3.6, z_name),
    ):
        ok = np.isfinite(v)
        ax.bar(x[ok], v[ok], color=[colour(float(s)) for s in v[ok]], width=0.7)
        _limits(ax, lines, v[ok], least)
        ax.set_ylabel(name)
        if not ok.any():
            ax.text(0.5, 0.5, f"no {name}", ha="center", va="center", transform=ax.transAxes)
    _groups(top, bottom, groups)
    if n <= 60:
        bottom.set_xticks(x, points, rotation=90, fontsize=6 if n > 24 else 8)
    else:
        bottom.set_xticks([])
        bottom.set_xlabel(f"Measurement point ({n}, labels not written)")
    top.set_title(title, pad=14)  # room for the group names above the bars
    return fig


def _groups(top: Axes, bottom: Axes, groups: Sequence[str]) -> None:
    """Grey separators between runs of the same group and the group's name above them."""
    for start, end in _runs(groups):
        if start:
            for ax in (top, bottom):
                ax.axvline(start - 0.5, color="#adb5bd", lw=0.8)
        top.text((start + end - 1) / 2, 1.02, groups[start], ha="center", va="bottom",
                 fontsize=7, transform=top.get_xaxis_transform())  # fmt: skip


lab_overview_chart = _svg_of(lab_overview_figure)
