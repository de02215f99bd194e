"""``fmurunner.plot``: a result drawn with matplotlib, as ``runner simulate --plot`` draws it."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ._engine import RunnerError

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _label(name: str, frame: pd.DataFrame) -> tuple[str, float, float]:
    """The axis label of column ``name`` in its display unit, and the conversion to it."""
    display = frame.attrs.get("display_units", {}).get(name)
    if display is not None:
        unit, factor, offset = display
    else:
        unit, factor, offset = frame.attrs.get("units", {}).get(name), 1.0, 0.0
    label = name if unit in (None, "", "1") else f"{name} ({unit})"
    return label, float(factor), float(offset)


def plot(
    frame: pd.DataFrame, columns: Sequence[str] | None = None, x: str | None = None, path: str | None = None
) -> Figure:
    """Draws a result of :func:`simulate` (or a :class:`pandas.DataFrame` with a ``time`` column
    and the same ``attrs``) with matplotlib: one panel per output on a shared time axis, each
    in its display unit (``df.attrs["display_units"]``, e.g. an angle in degrees), labelled
    ``name (unit)``, as ``runner simulate --plot`` draws it.

    ``columns`` chooses the columns (default: every float column but ``time``); ``x`` plots
    against another column than ``time``; ``path`` also saves the figure there (PNG, SVG, PDF by
    its extension). Returns the matplotlib ``Figure``. Needs matplotlib
    (``pip install matplotlib``).
    """
    try:
        import matplotlib.pyplot as plt
    except ImportError:
        raise RunnerError("fmurunner.plot needs matplotlib: pip install matplotlib") from None
    if not isinstance(frame, pd.DataFrame):
        raise RunnerError("plot() takes the DataFrame simulate() returned")
    x_name = x if x is not None else "time"
    if x_name not in frame.columns:
        raise RunnerError(f"the DataFrame has no column '{x_name}' to plot against (its columns are {', '.join(map(str, frame.columns))})")
    if columns is None:
        chosen = [str(c) for c in frame.columns if c != x_name and pd.api.types.is_float_dtype(frame[c])]
    else:
        chosen = [str(c) for c in columns]
        missing = [c for c in chosen if c not in frame.columns]
        if missing:
            raise RunnerError(f"the DataFrame has no column {missing[0]!r} (its columns are {', '.join(map(str, frame.columns))})")
    if not chosen:
        raise RunnerError("nothing to plot: the DataFrame has no float column besides the x axis; choose columns=")
    x_label, x_factor, x_offset = _label(x_name, frame)
    xs = frame[x_name].to_numpy(dtype=float) * x_factor + x_offset
    figure, axes = plt.subplots(len(chosen), 1, sharex=True, squeeze=False, figsize=(8.0, 1.0 + 2.0 * len(chosen)))
    for ax, name in zip(axes[:, 0], chosen):
        label, factor, offset = _label(name, frame)
        ys: Any = frame[name].to_numpy(dtype=float) * factor + offset
        ax.plot(xs, np.asarray(ys), color="#4e79a7", linewidth=1.2)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel(x_label)
    model = frame.attrs.get("model_name")
    title = f"{model}: outputs" if model else "outputs"
    if x is not None:
        title += f" against {x}"
    axes[0, 0].set_title(title)
    figure.tight_layout()
    if path is not None:
        figure.savefig(path, dpi=100)
    return figure
