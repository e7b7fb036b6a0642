"""The report's captions describe the figures as they are drawn."""

from pathlib import Path

import numpy as np

from dashpot import plots

REPORT = Path(__file__).resolve().parents[1] / "workflow" / "report"


def _caption(name):
    return " ".join((REPORT / f"{name}.rst").read_text(encoding="utf-8").split())


def test_intervals_caption_names_both_residual_panels():
    """With known timing errors the figure has three panels: the residuals in σ and, below
    them, in time units (the caption said σ "else in ms", as if there were one)."""
    n = np.arange(10)
    observed = 0.5 * 0.9 ** n
    fig = plots.intervals_figure(n, observed, np.full(10, 1e-5), {"Ia": observed * 1.0001})
    assert len(fig.axes) == 3
    caption = _caption("intervals")
    assert "Middle" in caption and "units of σ" in caption
    assert "Bottom: the same residuals in time units" in caption and "µs" in caption


def test_selection_caption_explains_qaic():
    fig = plots.selection_figure(["Ia", "IIa"], [0.5, 0.5], [0.0, 0.1], criterion="QAIC")
    assert "QAIC" in fig.axes[0].get_title()
    assert "ΔQAIC" in _caption("selection")
