"""One execution layer for independent tasks: serial, local processes, or a Dask cluster.

Studies and sweeps (regulation sweeps over frequencies x states x gains x seeds, randomised
diagnosis proofs, identification studies) are made of independent tasks.  :func:`run_tasks`
runs them on the engine the caller names and hands the results back **in task order**,
whatever order they finish in, so a distributed run equals the serial one bit for bit when the
tasks themselves are deterministic.

Schedulers (the ``scheduler`` argument, and ``--scheduler`` on the command line):

``"serial"``
    In this process, one task after the other.
``"processes"`` or ``"processes:N"``
    ``N`` local worker processes (:class:`concurrent.futures.ProcessPoolExecutor`; default
    ``N``: the cores this process may use).  No Dask needed.
``"local"`` or ``"local:N"``
    A Dask ``LocalCluster`` with ``N`` single-threaded worker processes, started for the run
    and closed after it (needs ``pip install "preisach[distributed]"``).
``"tcp://HOST:PORT"`` (or any other Dask scheduler address)
    A running Dask cluster (``dask scheduler`` / ``dask worker HOST:PORT``).

A ready ``distributed.Client`` can be passed as ``client=`` instead.

Large objects every task needs (models, recordings, plants) go in ``shared``: they are sent to
the workers once (``Client.scatter(..., broadcast=True)`` on Dask, the pool initializer for local
processes) and reach the task function as keyword arguments, never pickled per task.

**Resuming.**  With ``store=DIR`` every finished result is written to ``DIR/<key>.pkl``
(atomically: written beside, flushed to disk, renamed) as soon as it arrives; a rerun with the
same store loads those and runs only the missing tasks.  So a study interrupted (Ctrl-C, a lost
machine) keeps what it finished.  A task whose worker dies is retried by Dask (``retries``);
local process pools restart the run's remaining tasks on a broken pool once.

**Seeds.**  Randomness belongs to the task, never to the worker: derive a task's seed from the
study's seed and the task's key with :func:`task_seed`, so any scheduler, worker count or resume
gives the same numbers.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import re
import time
import zlib
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from ._io import atomic_write, write_text
from ._progress import progress_bar

if TYPE_CHECKING:  # pragma: no cover
    import argparse

    from distributed import Client, LocalCluster

__all__ = [
    "SCHEDULER_HELP",
    "TaskStore",
    "add_scheduler_argument",
    "available_cores",
    "parse_scheduler",
    "run_tasks",
    "task_seed",
]

T = TypeVar("T")
R = TypeVar("R")

#: Help text of the ``--scheduler`` option.
SCHEDULER_HELP = (
    "where independent tasks run: 'serial', 'processes[:N]' (local processes, the default "
    "for studies), 'local[:N]' (a Dask LocalCluster of N workers) or 'tcp://HOST:PORT' (a "
    'running Dask scheduler); the Dask ones need `pip install "preisach[distributed]"`'
)

_KEY_RE = re.compile(r"[^A-Za-z0-9_.=+-]")


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS tells, else the count)."""
    try:
        return len(os.sched_getaffinity(0))  # type: ignore[attr-defined,unused-ignore]
    except (AttributeError, OSError):  # pragma: no cover - platforms without affinity
        return os.cpu_count() or 1


def task_seed(seed: int, key: str) -> int:
    """Derive a task's own seed from the study's ``seed`` and the task's ``key``.

    Uses a CRC-32 of the key (not Python's salted ``hash``), so it is the same in every
    process, on every machine and in every run.

    Parameters
    ----------
    seed : int
        The study's seed (non-negative).
    key : str
        The task's key.

    Returns
    -------
    int
        A seed in ``[0, 2**63)``.

    """
    import numpy as np

    if int(seed) < 0:
        raise ValueError(f"seed: need a non-negative integer, got {seed}")
    ss = np.random.SeedSequence([int(seed), zlib.crc32(key.encode("utf-8"))])
    return int(ss.generate_state(1, dtype=np.uint64)[0] >> np.uint64(1))


def parse_scheduler(spec: str | None) -> tuple[str, int | str | None]:
    """Split a scheduler specification into its kind and argument.

    Parameters
    ----------
    spec : str or None
        ``"serial"``, ``"processes[:N]"``, ``"local[:N]"`` or a Dask address
        (``"tcp://HOST:PORT"``, ``"tls://..."``, ...); ``None`` means ``"serial"``.

    Returns
    -------
    (kind, arg)
        ``("serial", None)``, ``("processes", N or None)``, ``("local", N or None)`` or
        ``("address", address)``.

    Raises
    ------
    ValueError
        On anything else, or a worker count below 1.

    """
    if spec is None or spec == "serial":
        return ("serial", None)
    s = str(spec).strip()
    if "://" in s:
        return ("address", s)
    kind, _, n = s.partition(":")
    if kind not in ("processes", "local"):
        raise ValueError(
            f"scheduler: expected 'serial', 'processes[:N]', 'local[:N]' or a Dask address "
            f"such as 'tcp://HOST:8786', got {spec!r}"
        )
    if not n:
        return (kind, None)
    try:
        count = int(n)
    except ValueError:
        raise ValueError(f"scheduler: worker count in {spec!r} is not a whole number") from None
    if count < 1:
        raise ValueError(f"scheduler: need at least 1 worker, got {count} in {spec!r}")
    return (kind, count)


def add_scheduler_argument(parser: argparse.ArgumentParser, default: str = "processes") -> None:
    """Add ``--scheduler`` and ``--store`` to an :mod:`argparse` parser (studies, sweeps)."""
    parser.add_argument(
        "--scheduler", default=default, help=SCHEDULER_HELP + f" (default: {default})"
    )
    parser.add_argument(
        "--store",
        metavar="DIR",
        default=None,
        help="keep every finished task's result in DIR; a rerun with the same DIR skips them "
        "(resume after an interruption)",
    )


class TaskStore:
    """Finished task results on disk, one pickle per task key (written atomically).

    Parameters
    ----------
    path : str or path-like
        The folder (created when missing).
    tag : str
        What the results belong to (e.g. the study's name and parameters); a store made for
        another tag is refused, so a rerun with other parameters never mixes results.

    """

    def __init__(self, path: str | os.PathLike[str], tag: str = "") -> None:
        self.path = Path(path)
        if self.path.exists() and not self.path.is_dir():
            raise ValueError(f"store: {self.path} exists and is not a folder")
        self.path.mkdir(parents=True, exist_ok=True)
        stamp = self.path / "TAG"
        digest = hashlib.sha256(tag.encode("utf-8")).hexdigest()
        if stamp.exists():
            old = stamp.read_text(encoding="utf-8").strip()
            if old != digest:
                raise ValueError(
                    f"store: {self.path} holds results of another study or other parameters; "
                    "use another folder (or remove it) to start afresh"
                )
        else:
            write_text(stamp, digest + "\n", what="task store tag")

    def _file(self, key: str) -> Path:
        safe = _KEY_RE.sub("_", key)
        if safe != key or len(safe) > 120:
            safe = safe[:80] + "-" + hashlib.sha1(key.encode("utf-8")).hexdigest()[:16]
        return self.path / f"{safe}.pkl"

    def __contains__(self, key: object) -> bool:
        return isinstance(key, str) and self._file(key).is_file()

    def load(self, key: str) -> Any:
        """Return the stored result of ``key`` (``KeyError`` when not stored)."""
        f = self._file(key)
        if not f.is_file():
            raise KeyError(key)
        with open(f, "rb") as fh:
            stored_key, value = pickle.load(fh)
        if stored_key != key:  # pragma: no cover - a hash collision of mangled keys
            raise KeyError(key)
        return value

    def save(self, key: str, value: Any) -> None:
        """Store ``value`` as the result of ``key`` (atomically)."""
        data = pickle.dumps((key, value), protocol=pickle.HIGHEST_PROTOCOL)
        atomic_write(self._file(key), lambda f: f.write(data), binary=True, what="task result")


# ----------------------------------------------------------------------------------------
# workers
# ----------------------------------------------------------------------------------------
_SHARED: dict[str, Any] = {}


def _init_worker(shared: Mapping[str, Any]) -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    _SHARED.clear()
    _SHARED.update(shared)


def _call_shared(fn: Callable[..., Any], task: Any) -> Any:
    return fn(task, **_SHARED)


def _call_dask(fn: Callable[..., Any], task: Any, **shared: Any) -> Any:
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        return fn(task, **shared)
    with threadpool_limits(1):
        return fn(task, **shared)


def _dask_client(kind: str, arg: int | str | None) -> tuple[Client, LocalCluster | None]:
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ImportError(
            'the Dask schedulers need the distributed extra: pip install "preisach[distributed]"'
        ) from None
    if kind == "address":
        return Client(str(arg)), None
    n = int(arg) if arg is not None else available_cores()
    cluster = LocalCluster(
        n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None
    )
    return Client(cluster), cluster


def run_tasks(
    fn: Callable[..., R],
    tasks: Sequence[T],
    *,
    keys: Sequence[str] | None = None,
    scheduler: str | None = "serial",
    client: Client | None = None,
    shared: Mapping[str, Any] | None = None,
    store: str | os.PathLike[str] | TaskStore | None = None,
    store_tag: str = "",
    retries: int = 2,
    progress: bool = False,
    desc: str = "tasks",
    on_result: Callable[[int, R], None] | None = None,
) -> list[R]:
    """Run ``fn(task, **shared)`` for every task; results in task order.

    Parameters
    ----------
    fn : callable
        A module-level function (it is pickled by reference for the process and Dask
        schedulers): ``fn(task, **shared) -> result``.
    tasks : sequence
        The tasks (small, picklable: parameters, seeds, names).
    keys : sequence of str, optional
        A stable key per task (needed with ``store``); default ``"task-<index>"``.
    scheduler : str, optional
        See the module docstring; ignored when ``client`` is given.
    client : distributed.Client, optional
        A running Dask client to use (not closed here).
    shared : mapping, optional
        Large objects every task needs, sent to each worker once.
    store : str, path-like or TaskStore, optional
        Keep finished results there and skip the ones already there (resume).
    store_tag : str
        What the store's results belong to (see :class:`TaskStore`).
    retries : int
        How often Dask reruns a task whose worker died or that raised.
    progress : bool
        Draw a progress bar (terminal or Jupyter; see :mod:`preisach._progress`).
    desc : str
        The progress bar's label.
    on_result : callable, optional
        ``on_result(index, result)`` as each task finishes (also for results loaded from the
        store), in finishing order.

    Returns
    -------
    list
        ``[fn(tasks[0]), fn(tasks[1]), ...]``.

    """
    task_list = list(tasks)
    n = len(task_list)
    key_list = [f"task-{i}" for i in range(n)] if keys is None else [str(k) for k in keys]
    if len(key_list) != n:
        raise ValueError(f"keys: need one per task ({n}), got {len(key_list)}")
    if len(set(key_list)) != n:
        raise ValueError("keys: task keys must be unique")
    if retries < 0:
        raise ValueError(f"retries: need >= 0, got {retries}")
    shared_d = dict(shared or {})
    st: TaskStore | None
    if store is None or isinstance(store, TaskStore):
        st = store
    else:
        st = TaskStore(store, store_tag)

    results: list[Any] = [None] * n
    have = [False] * n
    if st is not None:
        for i, k in enumerate(key_list):
            if k in st:
                results[i] = st.load(k)
                have[i] = True
                if on_result is not None:
                    on_result(i, results[i])
    todo = [i for i in range(n) if not have[i]]
    bar = progress_bar(n, desc, enabled=progress, unit="task")
    bar.update(n - len(todo))

    def finish(i: int, r: Any) -> None:
        results[i] = r
        have[i] = True
        if st is not None:
            st.save(key_list[i], r)
        bar.update(1)
        if on_result is not None:
            on_result(i, r)

    try:
        if todo:
            if client is not None:
                _run_dask(client, fn, task_list, key_list, todo, shared_d, retries, finish)
            else:
                kind, arg = parse_scheduler(scheduler)
                if kind == "serial":
                    for i in todo:
                        finish(i, fn(task_list[i], **shared_d))
                elif kind == "processes":
                    workers = int(arg) if arg is not None else available_cores()
                    _run_processes(fn, task_list, todo, shared_d, workers, finish)
                else:
                    c, cluster = _dask_client(kind, arg)
                    try:
                        _run_dask(c, fn, task_list, key_list, todo, shared_d, retries, finish)
                    finally:
                        c.close()
                        if cluster is not None:
                            cluster.close()
    finally:
        bar.close()
    return results


def _run_processes(
    fn: Callable[..., Any],
    tasks: list[Any],
    todo: list[int],
    shared: dict[str, Any],
    workers: int,
    finish: Callable[[int, Any], None],
) -> None:
    left = list(todo)
    for attempt in range(2):  # a broken pool (a worker killed) gets one fresh pool
        with ProcessPoolExecutor(
            max_workers=min(workers, len(left)), initializer=_init_worker, initargs=(shared,)
        ) as ex:
            futs: dict[Future[Any], int] = {ex.submit(_call_shared, fn, tasks[i]): i for i in left}
            try:
                pending = set(futs)
                while pending:
                    done, pending = wait(pending, return_when=FIRST_COMPLETED)
                    for f in done:
                        i = futs[f]
                        finish(i, f.result())
                        left.remove(i)
                return
            except BrokenProcessPool:
                if attempt == 1:
                    raise
            except BaseException:
                for f in futs:
                    f.cancel()
                raise


def _run_dask(
    client: Client,
    fn: Callable[..., Any],
    tasks: list[Any],
    keys: list[str],
    todo: list[int],
    shared: dict[str, Any],
    retries: int,
    finish: Callable[[int, Any], None],
) -> None:
    from distributed import as_completed

    # scatter([v]) ships v whole (scatter(v) would split a list or dict into its items)
    # (hash=False: fresh keys per run, so a cancelled earlier run cannot release them)
    scattered = {k: client.scatter([v], broadcast=True, hash=False)[0] for k, v in shared.items()}
    stamp = f"{time.time_ns():x}"
    futs = {}
    for i in todo:
        f = client.submit(
            _call_dask,
            fn,
            tasks[i],
            key=f"preisach-{_KEY_RE.sub('_', keys[i])[:60]}-{i}-{stamp}",
            retries=retries,
            pure=False,
            **scattered,
        )
        futs[f] = i
    try:
        for f in as_completed(list(futs)):
            finish(futs[f], f.result())
    except BaseException:
        client.cancel(list(futs))
        raise
