"""Atomic file writes: every file :mod:`preisach` writes goes through :func:`atomic_write`.

The promise (docs/RELIABILITY.md): a file the tool writes is either the complete new content
or, if anything fails (a full disk, an I/O error, a signal, an exception while producing the
content), the previous file untouched and no temporary file left behind.

How: the content goes to a temporary file beside the target (same directory, so the rename
cannot cross a file system), the file is flushed and ``fsync``'ed, renamed over the target with
:func:`os.replace` (atomic on POSIX), and the directory is ``fsync``'ed so the rename itself
survives a power cut.  Before writing, the target is checked:

- a directory, a device node (``/dev/null``, ``/dev/full``), a FIFO or a socket is refused
  with an :class:`OSError` naming the file (replacing ``/dev/null`` by a regular file as root
  is data loss of the worst kind);
- a symbolic link is never replaced: the write goes through the link to its target (the
  final path, resolved), which is itself checked and replaced atomically in its own directory;
  the link stays a link.

An existing file's permission bits are kept; a new file gets ``0o666`` minus the umask, as
:func:`open` would give it.  Errors are :class:`OSError` with ``errno`` set and a message that
names the file (``filename`` is the target, not the temporary file).

The streaming recordings of the trial runner are the one exception by design: they are
written in place as the trial runs (a crash must leave every row up to the crash readable),
and end with ``# end_status: ...`` (see :class:`preisach.recording.RecordingWriter`).
"""

from __future__ import annotations

import errno
import json
import os
import secrets
import stat
from collections.abc import Callable
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["atomic_write", "check_target", "save_figure", "write_json", "write_text"]

PathLike = str | os.PathLike[str]


def _kind(mode: int) -> str:
    for test, name in (
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def check_target(path: PathLike, what: str = "file") -> Path:
    """Return the path a write to ``path`` replaces (symlinks resolved), refusing unsafe ones.

    Parameters
    ----------
    path : str or path-like
        The file to be written.
    what : str
        What the file is, for the messages (e.g. ``"model"``).

    Returns
    -------
    pathlib.Path
        ``path`` itself, or the final target of a symbolic link (the link is kept).

    Raises
    ------
    IsADirectoryError
        If the target is a directory.
    OSError
        ``errno.EINVAL`` if it is a device node, FIFO or socket; ``ENOENT`` if its directory
        does not exist; ``ELOOP`` for a symlink loop.

    """
    p = Path(os.fspath(path))
    if not p.name:
        raise IsADirectoryError(errno.EISDIR, f"cannot write the {what}: no file name", str(p))
    if p.is_symlink():
        target = Path(os.path.realpath(p))
        if target.is_symlink():  # realpath stops at a loop
            raise OSError(errno.ELOOP, f"cannot write the {what}: symbolic link loop", str(p))
        p = target
    try:
        st = os.stat(p)
    except FileNotFoundError:
        parent = p.parent
        if not parent.is_dir():
            raise FileNotFoundError(
                errno.ENOENT,
                f"cannot write the {what}: the folder {str(parent)!r} does not exist",
                str(p),
            ) from None
        return p
    if stat.S_ISDIR(st.st_mode):
        raise IsADirectoryError(
            errno.EISDIR, f"cannot write the {what}: the path is a directory", str(p)
        )
    if not stat.S_ISREG(st.st_mode):
        raise OSError(
            errno.EINVAL,
            f"cannot write the {what}: the path is {_kind(st.st_mode)}; preisach writes only "
            "regular files (and never replaces a device node)",
            str(p),
        )
    return p


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:  # e.g. a directory we may write to but not open; the rename is done
        return
    try:
        os.fsync(fd)
    except OSError as exc:  # some file systems do not sync directories
        if exc.errno not in (errno.EINVAL, errno.ENOTSUP, errno.EBADF, errno.EROFS):
            raise
    finally:
        os.close(fd)


def atomic_write(
    path: PathLike,
    write: Callable[[IO[Any]], object],
    *,
    binary: bool = False,
    what: str = "file",
    fsync: bool = True,
) -> Path:
    """Write a file atomically: to a temporary file beside it, ``fsync``, rename, sync the folder.

    Parameters
    ----------
    path : str or path-like
        Destination (see :func:`check_target`: a symlink is written through, a directory or
        device node refused).
    write : callable
        ``write(f)`` writes the content to the open temporary file ``f`` (text mode, UTF-8,
        no newline translation, unless ``binary``).
    binary : bool
        Open the temporary file in binary mode.
    what : str
        What the file is, for error messages.
    fsync : bool
        ``fsync`` the file and its folder (default).  Only tests turn this off.

    Returns
    -------
    pathlib.Path
        The file written (the symlink's target when ``path`` is a link).

    Raises
    ------
    OSError
        With ``errno`` and the file's name, when the target is refused or any step fails; the
        previous file is then unchanged and the temporary file removed.  Anything ``write``
        raises propagates the same way.

    """
    target = check_target(path, what)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except OSError:
        mode = None
    fd = -1
    try:
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
            f: IO[Any] = (
                os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", encoding="utf-8", newline="")
            )
        except BaseException:
            if fd >= 0:
                os.close(fd)
            raise
        with f:
            write(f)
            f.flush()
            if fsync:
                os.fsync(f.fileno())
        if mode is not None:
            os.chmod(tmp, mode)
        os.replace(tmp, target)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError) and exc.filename != os.fspath(target):
            reason = exc.strerror or str(exc)
            raise OSError(
                exc.errno or errno.EIO,
                f"cannot write the {what} ({reason}); the previous file, if any, is unchanged",
                os.fspath(target),
            ) from exc
        raise
    if fsync:
        _fsync_dir(target.parent)
    return target


def write_text(path: PathLike, text: str, *, what: str = "file") -> Path:
    """Write ``text`` (UTF-8) atomically; see :func:`atomic_write`."""
    return atomic_write(path, lambda f: f.write(text), what=what)


def write_json(path: PathLike, obj: Any, *, what: str = "JSON file", **dumps_kwargs: Any) -> Path:
    """Write ``json.dumps(obj, **dumps_kwargs)`` plus a newline atomically.

    The text is built before the file is touched, so an object that does not serialise
    leaves no file and no temporary file.
    """
    text = json.dumps(obj, **dumps_kwargs) + "\n"
    return write_text(path, text, what=what)


def save_figure(fig: Figure, path: PathLike, **savefig_kwargs: Any) -> Path:
    """Save a matplotlib figure atomically (the format from the suffix, as ``savefig`` does).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or path-like
        Destination; its suffix (``.png``, ``.pdf``, ``.svg``, ...) selects the format unless
        ``format=`` is given.
    **savefig_kwargs
        Passed to :meth:`matplotlib.figure.Figure.savefig`.

    """
    fmt = savefig_kwargs.pop("format", None) or Path(os.fspath(path)).suffix[1:].lower() or None
    return atomic_write(
        path, lambda f: fig.savefig(f, format=fmt, **savefig_kwargs), binary=True, what="figure"
    )


def npz_load_error(exc: BaseException) -> str:
    """Describe why :func:`numpy.load` could not read a file, for a one-line message.

    numpy's own text for a file that is not an archive advises loading it with
    ``allow_pickle`` - unsafe for a file of unknown origin, so never repeated here.
    """
    import zipfile

    if isinstance(exc, EOFError):
        return "the file is empty"
    if isinstance(exc, zipfile.BadZipFile):
        return f"not a valid .npz archive: truncated or damaged ({exc})"
    text = str(exc)
    if "pickle" in text:
        return (
            "not an .npz archive (a text file such as a CSV recording, or another format; "
            "is the order of the arguments right?)"
        )
    return text
