"""Progress bars for every call that can take more than a few seconds, built on ``tqdm.auto``.

One helper, :func:`progress_bar`, used by :func:`preisach.diagnose.diagnose`,
:func:`preisach.experiments.regulation_sweep`, :func:`preisach.identify.identify_lsq`
(cross-validation), ``preisach demo``, ``preisach trial run`` and the studies in ``scripts/``.
Each of them takes ``progress=False`` (the command line: ``-q``) to draw nothing.

Where the bar goes:

* in Jupyter: a widget when ``ipywidgets`` is installed, else a text bar redrawn in place
  (``tqdm.auto``'s choice; its warnings about the missing widgets are silenced);
* on a terminal: a text bar on stderr, redrawn in place;
* anywhere else (a log file, a pipe, a captured test): plain lines, at most one every
  ``log_interval`` seconds plus the final state - no carriage returns in logs.

A bar shows only once its task has run ``delay`` seconds (default 2 s): quick calls stay quiet.

``tqdm`` is imported when the first bar is made, never at ``import preisach``.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Callable
from types import TracebackType
from typing import IO, Any, Protocol

__all__ = ["ProgressBar", "line_progress", "progress_bar"]


class ProgressBar(Protocol):
    """What the package uses of a ``tqdm`` bar (``tqdm`` itself carries no types)."""

    n: float
    total: float | None

    def update(self, n: float = 1) -> bool | None: ...  # noqa: D102

    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None: ...  # noqa: D102

    def set_description_str(self, desc: str | None = None, refresh: bool = True) -> None: ...  # noqa: D102

    def write(self, s: str, file: IO[str] | None = None) -> None: ...  # noqa: D102

    def close(self) -> None: ...  # noqa: D102

    def __enter__(self) -> ProgressBar: ...  # noqa: D105

    def __exit__(  # noqa: D105
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...


def _isatty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


def _in_jupyter() -> bool:
    """Whether we run in a Jupyter kernel (IPython under ipykernel)."""
    shell = sys.modules.get("IPython")
    if shell is None or "ipykernel" not in sys.modules:
        return False
    ip = shell.get_ipython()
    return ip is not None and "IPKernelApp" in getattr(ip, "config", {})


class _Lines:
    """File for tqdm off a terminal: every redraw becomes one line, without carriage returns."""

    def __init__(self, stream: Any) -> None:
        self.stream = stream
        self.last = ""

    def write(self, text: str) -> None:
        line = text.replace("\r", "").strip()
        if line and line != self.last:
            self.last = line
            self.stream.write(line + "\n")

    def flush(self) -> None:
        getattr(self.stream, "flush", lambda: None)()


def progress_bar(
    total: float | None = None,
    desc: str = "",
    *,
    enabled: bool = True,
    unit: str = "it",
    leave: bool | None = None,
    file: Any = None,
    log_interval: float = 10.0,
    delay: float = 2.0,
) -> ProgressBar:
    """Return a ``tqdm`` progress bar (``update``, ``set_postfix_str``, ``close``, context).

    Parameters
    ----------
    total : float, optional
        Number of units of the whole task; ``None`` when unknown (a counter and a rate).
    desc : str
        Text before the bar.
    enabled : bool
        ``False`` returns a disabled bar: every method works and nothing is drawn.
    unit : str
        Name of one unit (``"trial"``, ``"fit"``, ``"sample"``).
    leave : bool, optional
        Keep the finished bar on screen; default: only when it is not nested in another bar
        (a sweep inside ``preisach demo`` disappears when done, the demo's own bar stays).
    file : file-like, optional
        Where a text bar goes; default ``sys.stderr``.
    log_interval : float
        Seconds between lines when ``file`` is neither a terminal nor a Jupyter output.
    delay : float
        Seconds before the bar first shows: a call that ends sooner draws nothing.

    Returns
    -------
    tqdm.tqdm
        Use it as a context manager, or call ``close()`` when done.

    """
    stream = sys.stderr if file is None else file
    options: dict[str, Any] = {
        "total": total,
        "desc": desc,
        "unit": unit,
        "leave": leave,
        "delay": delay,
    }
    if not enabled:
        from tqdm.std import tqdm

        bar: ProgressBar = tqdm(disable=True, **options)
        return bar
    if _in_jupyter() or _isatty(stream):
        from tqdm import TqdmWarning

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TqdmWarning)  # "ipywidgets not found", "experimental"
            from tqdm.auto import tqdm as auto_tqdm
        bar = auto_tqdm(file=stream, dynamic_ncols=True, **options)
        return bar
    from tqdm.std import tqdm

    bar = tqdm(file=_Lines(stream), mininterval=log_interval, ascii=True, ncols=100, **options)
    return bar


def line_progress(
    progress: bool | Callable[[str], None] | None, desc: str, *, unit: str = "step"
) -> tuple[Callable[[str], None] | None, ProgressBar]:
    """Turn a ``progress`` argument into a line callback and the bar that shows it.

    Functions that report progress as text lines (``diagnose``: one line per stage and per
    candidate fit) accept ``progress=True`` (a bar that counts the lines and shows the last
    one), ``False``/``None`` (nothing) or a callable (gets every line, e.g. ``print``).

    Parameters
    ----------
    progress : bool, callable or None
        The caller's ``progress`` argument.
    desc : str
        Text before the bar.
    unit : str
        Name of one line's unit.

    Returns
    -------
    callback : callable or None
        Pass it where a line callback is expected.
    bar : tqdm.tqdm
        Close it when done (a disabled bar when ``progress`` is not ``True``).

    """
    if callable(progress):
        return progress, progress_bar(enabled=False)
    bar = progress_bar(None, desc, enabled=bool(progress), unit=unit)
    if not progress:
        return None, bar

    def show(line: str) -> None:
        bar.set_postfix_str(" ".join(line.split())[:70], refresh=False)
        bar.update(1)

    return show, bar
