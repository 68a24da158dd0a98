"""Helpers shared by the figure modules."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure


def figure(fig: Figure | None, **kwargs: object) -> Figure:
    """Return ``fig``, or a new Figure (made with ``kwargs``) when it is ``None``."""
    if fig is not None:
        return fig
    from matplotlib.figure import Figure as _Figure

    return _Figure(**kwargs)  # type: ignore[arg-type]
