"""Figure helpers shared by every module that draws (matplotlib is imported only when one draws)."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d import Axes3D


def figure(fig: Figure | None, *, figsize: tuple[float, float]) -> Figure:
    """Return ``fig``, or a new Figure of ``figsize`` (inches) when it is ``None``."""
    if fig is not None:
        return fig
    from matplotlib.figure import Figure as _Figure

    return _Figure(figsize=figsize)


def figure_of(ax: Axes | Axes3D) -> Figure:
    """Return the (root) Figure an axes belongs to."""
    fig = ax.get_figure(root=True)
    if fig is None:
        raise ValueError("ax: the axes belong to no figure")
    return fig


def figure_and_axes(ax: Axes | None, *, figsize: tuple[float, float]) -> tuple[Figure, Axes]:
    """Return ``ax`` and its figure, or a new figure of ``figsize`` and its one axes."""
    if ax is not None:
        return figure_of(ax), ax
    fig = figure(None, figsize=figsize)
    return fig, fig.add_subplot()


def figure_and_axes3d(ax: Axes3D | None, *, figsize: tuple[float, float]) -> tuple[Figure, Axes3D]:
    """Return ``ax`` and its figure, or a new figure of ``figsize`` and its one 3-D axes."""
    if ax is not None:
        return figure_of(ax), ax
    fig = figure(None, figsize=figsize)
    return fig, fig.add_subplot(projection="3d")
