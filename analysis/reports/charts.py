"""PNG charts for the PDF reports (matplotlib Agg, object-oriented API, 200 dpi).

Plain numbers in, PNG bytes out.  ``metadata={"Software": None}`` and a fixed size make
the bytes depend on the data only, so a report renders byte-identically twice.
"""

from __future__ import annotations

import functools
import io
from collections.abc import Sequence
from typing import Any

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

matplotlib.use("Agg")

DPI = 200
OWN = "#d63384"
LAB = "#1f3a5f"
BAND = "#9ec5fe"
BAD = "#dc3545"
RC: dict[Any, Any] = {
    "font.family": "DejaVu Sans",
    "font.size": 8,
    "axes.spines.top": False,
    "axes.spines.right": False,
}


def _figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _png(fig: Figure) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, metadata={"Software": None})
    return buffer.getvalue()


def point_png(
    labels: Sequence[str],
    values: Sequence[float],
    expanded: Sequence[float],
    *,
    x_pt: float,
    u_x_pt_expanded: float,
    title: str,
    unit: str,
    highlight: str | None = None,
) -> bytes:
    """Each lab's result ± U against x_pt and its ±U band, for one measurement point."""
    with matplotlib.rc_context(RC):
        fig = _figure(6.4, 2.6)
        ax = fig.add_subplot()
        x = np.arange(len(labels))
        ax.axhspan(
            x_pt - u_x_pt_expanded,
            x_pt + u_x_pt_expanded,
            color=BAND,
            alpha=0.45,
            label="x_pt ± U(x_pt)",
        )
        ax.axhline(x_pt, color=LAB, lw=1, ls="--", label="x_pt")
        for i, label in enumerate(labels):
            colour = OWN if label == highlight else LAB
            ax.errorbar(
                x[i],
                values[i],
                yerr=expanded[i],
                fmt="o",
                ms=3,
                color=colour,
                ecolor=colour,
                capsize=2,
                lw=1,
            )
        ax.set_xticks(x, labels, rotation=90 if len(labels) > 14 else 0)
        ax.set_ylabel(f"Sensitivity ({unit})")
        ax.set_title(title)
        ax.legend(loc="best", fontsize=7, frameon=False)
        return _png(fig)


def en_png(
    labs: Sequence[str], max_en: Sequence[float], *, limit: float, highlight: str | None = None
) -> bytes:
    """Largest |En| of each lab over all points, with the compatibility limit."""
    with matplotlib.rc_context(RC):
        fig = _figure(6.4, 2.4)
        ax = fig.add_subplot()
        x = np.arange(len(labs))
        colours = [
            OWN if lab == highlight else (BAD if e > limit else LAB)
            for lab, e in zip(labs, max_en, strict=True)
        ]
        ax.bar(x, max_en, color=colours, width=0.6)
        ax.axhline(limit, color=BAD, lw=1, ls="--", label=f"|En| = {limit:g}")
        ax.set_xticks(x, labs, rotation=90 if len(labs) > 14 else 0)
        ax.set_ylabel("largest |En|")
        ax.set_title("Largest |En| per participant")
        ax.legend(loc="best", fontsize=7, frameon=False)
        return _png(fig)


@functools.lru_cache(maxsize=16)
def frequency_png(
    series: tuple[tuple[str, tuple[float, ...], tuple[float, ...]], ...], *, title: str, unit: str
) -> bytes:
    """Sensitivity against frequency, one line per (bench, direction, axis); cached, as
    every report of a run shows the same lines."""
    with matplotlib.rc_context(RC):
        fig = _figure(6.4, 2.8)
        ax = fig.add_subplot()
        for label, freqs, values in series:
            ax.plot(freqs, values, marker="o", ms=3, lw=1, label=label)
        ax.set_xlabel("Frequency (Hz)")
        ax.set_ylabel(f"Sensitivity ({unit})")
        ax.set_title(title)
        ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=6, frameon=False)
        return _png(fig)
