"""Fault matrix: bad inputs and injected faults over the ``preisach`` command line.

Every case runs ``python -m preisach.cli ...`` (or ``python -m preisach.trials``) in a child
process and is classified from what came back and what is left on disk:

- ``accepted``: exit 0 where the input is valid;
- ``clear error``: a non-zero exit code of the documented set (1, 2, 3, 129, 130, 143) with at
  most a few lines on stderr and no traceback;
- ``traceback``: a Python traceback on stderr (without ``--debug``);
- ``misleading``: exit 0 where the input is invalid, or an exit code outside the set;
- ``data lost``: a file that existed before is changed or gone after a failed command, a
  non-regular target (device node, FIFO) replaced, a temporary file left behind, or a refused
  trial folder modified;
- ``left driving``: a trial stopped without its output ramped to 0 V (the summary's
  ``final_output`` or the recording's last ``u`` not 0, or no ``end_status``).

Full disks are emulated with ``RLIMIT_FSIZE`` (``write`` fails with EFBIG where ENOSPC would),
signals are sent to running trials on the virtual rig and to diagnose and demo.  Prints one line
per case and the counts (docs/RELIABILITY.md quotes them).  Takes a few minutes (the diagnose and
demo cases dominate); Linux only, run as root it also tries a device node of its own.

    python scripts/fault_matrix.py [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from preisach import PreisachModel, Recording

CODES = {1, 2, 3, 129, 130, 143}


@dataclass
class Case:
    """One input or fault and what must hold afterwards."""

    name: str
    argv: list[str]
    valid: bool = False  # exit 0 expected
    fsize: int | None = None  # RLIMIT_FSIZE for the child (bytes)
    keep: list[Path] = field(default_factory=list)  # files that must be unchanged on failure
    special: list[Path] = field(default_factory=list)  # non-regular targets that must stay so
    folder: Path | None = None  # a folder no temp file may be left in
    # (signal, csv to watch, rows written first) or (signal, None, seconds to wait first)
    signal_after: tuple[int, Path | None, float] | None = None
    trial_out: Path | None = None  # a trial output folder to check for a ramp to 0 V
    env: dict[str, str] = field(default_factory=dict)
    module: str = "preisach.cli"
    check: Callable[[], str] | None = None  # extra check: "" if fine, else the data-loss reason


def _child_limits(fsize: int | None) -> Callable[[], None]:
    def apply() -> None:
        # A script started in the background inherits SIGINT ignored, and Python then leaves it
        # ignored: give the child the default, as a terminal would.
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        if fsize is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, resource.RLIM_INFINITY))

    return apply


def _rows(csv: Path) -> int:
    try:
        return sum(1 for line in csv.read_text().splitlines() if line[:1].isdigit())
    except OSError:
        return 0


def run_case(c: Case) -> tuple[str, str]:
    """Run one case; return (class, detail)."""
    before = {p: p.read_bytes() for p in c.keep if p.is_file()}
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", **c.env)
    proc = subprocess.Popen(
        [sys.executable, "-m", c.module, *c.argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=_child_limits(c.fsize),
    )
    try:
        if c.signal_after is not None:
            sig, csv, rows = c.signal_after
            deadline = time.monotonic() + (60 if csv is not None else rows)
            while time.monotonic() < deadline and proc.poll() is None:
                if csv is not None and _rows(csv) >= rows:
                    break
                time.sleep(0.05)
            if proc.poll() is None:
                proc.send_signal(sig)
        out, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    code = proc.returncode
    lost = []
    if code != 0:
        lost += [
            f"{p.name} changed" for p, b in before.items() if not p.is_file() or p.read_bytes() != b
        ]
    for p in c.special:
        if p.is_symlink() or not (p.exists() and not stat.S_ISREG(os.lstat(p).st_mode)):
            lost.append(f"{p.name} replaced")
    if c.folder is not None:
        lost += [f"temp file {p.name}" for p in c.folder.rglob("*.tmp")]
    if c.check is not None and (why := c.check()):
        lost.append(why)
    if c.trial_out is not None:
        driving = _left_driving(c.trial_out)
        if driving:
            return "left driving", driving
    if lost:
        return "data lost", "; ".join(lost)
    if "Traceback" in err:
        return "traceback", err.strip().splitlines()[-1][:100]
    if code == 0:
        return ("accepted", "exit 0") if c.valid else ("misleading", "exit 0 on a bad input")
    if code not in CODES or c.valid:
        return "misleading", f"exit {code}: {err.strip()[:100]}"
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    if code == 2 and lines and lines[0].startswith("usage:"):  # argparse: usage, then one line
        lines = lines[-1:]
    if len(lines) > 12 or not lines:
        return "misleading", f"exit {code} with {len(lines)} lines on stderr"
    return "clear error", f"exit {code}: {lines[-1][:110]}"


def _left_driving(out: Path) -> str:
    summary = out / "summary.json"
    if not summary.is_file():
        return "no summary.json"
    doc = json.loads(summary.read_text())
    if doc.get("final_output") != 0.0:
        return f"summary final_output = {doc.get('final_output')!r}"
    for step in doc.get("steps", []):
        f = Path(step["file"])
        try:
            rec = Recording.load(f)
        except Exception as exc:  # noqa: BLE001
            return f"{f.name}: {exc}"
        if "end_status" not in rec.metadata:
            return f"{f.name} has no end_status"
    return ""


TRIAL_HEAD = """
[trial]
sample_time = 0.001
[device]
kind = "sim"
{device}
[output]
name = "V_in"
channel = 1
range = [-10.0, 10.0]
calibration = "ss15-b"
[input]
name = "V_out"
channel = 1
range = [-5.0, 5.0]
[safety]
max_consecutive_missed = -1
"""


def build_cases(d: Path) -> list[Case]:
    """Write the inputs into ``d`` and return the cases."""
    m = PreisachModel.builtin(levels=21)
    from preisach.waveforms import fod_sweep

    wave = fod_sweep(11, u_min=-100, u_max=100, frequency=1.0, sample_time=2e-3)
    rec = Recording.from_arrays(u=wave.u, y=m.simulate(wave.u).output, sample_time=2e-3)
    rec.metadata["experiment"] = "fod_sweep"
    good = d / "rec.csv"
    rec.save(good)
    rec.save(d / "rec.npz")
    model = d / "model.npz"
    m.save(model)

    def w(name: str, data: bytes | str) -> Path:
        p = d / name
        p.write_bytes(data.encode() if isinstance(data, str) else data)
        return p

    empty = w("empty.csv", "")
    header_only = w("header_only.csv", "t,u,y\n")
    garbage = w("garbage.csv", os.urandom(2000))
    latin = w("latin1.csv", "t,u,y\n0,1,\xe9\n".encode("latin-1"))
    nan = w("nan.csv", "t,u,y\n0,1,2\n0.001,nan,3\n0.002,1,2\n")
    back = w("backwards.csv", "t,u,y\n0,1,2\n0.002,1,2\n0.001,1,2\n")
    cols = w("no_y.csv", "t,u,v\n0,1,2\n0.001,1,3\n")
    npz_as_csv = w("model_as.csv", model.read_bytes())
    empty_model = w("empty.npz", "")
    trunc_model = w("trunc.npz", model.read_bytes()[:400])
    rand_model = w("random.npz", os.urandom(3000))
    np.save(d / "array.npy", np.arange(5.0))
    arr = d / "array.npy"
    csv_as_model = w("csv_as.npz", good.read_bytes())
    bad_json_meta = w("badmeta.npz", b"PK\x03\x04" + os.urandom(200))

    cases: list[Case] = []
    add = cases.append
    out = d / "out"
    out.mkdir()
    # ---- inputs to identify / verify / diagnose ---------------------------------------------
    add(
        Case(
            "identify a good recording",
            ["identify", str(good), "-o", str(out / "m1.npz"), "--levels", "11"],
            valid=True,
        )
    )
    add(
        Case(
            "identify an NPZ recording",
            ["identify", str(d / "rec.npz"), "-o", str(out / "m2.npz"), "--levels", "11"],
            valid=True,
        )
    )
    for p in (
        d / "missing.csv",
        empty,
        header_only,
        garbage,
        latin,
        nan,
        back,
        cols,
        npz_as_csv,
        bad_json_meta,
        d,
    ):
        add(Case(f"identify {p.name}", ["identify", str(p), "-o", str(out / "x.npz")]))
    for bad in (["--levels", "2"], ["--levels", "100000"], ["--method", "nope"], ["--bogus"]):
        add(
            Case(
                f"identify {' '.join(bad)}", ["identify", str(good), "-o", str(out / "x.npz"), *bad]
            )
        )
    for p in (empty_model, trunc_model, rand_model, arr, csv_as_model, d / "missing.npz"):
        add(Case(f"verify model {p.name}", ["verify", str(p), str(good)]))
        add(
            Case(
                f"diagnose model {p.name}",
                ["diagnose", str(p), str(good), "--json", str(out / "d.json")],
            )
        )
    add(Case("verify swapped arguments", ["verify", str(good), str(model)]))
    add(
        Case(
            "verify --properties without loops",
            ["verify", str(model), str(good), "--properties"],
            valid=True,
        )
    )
    # ---- refused output targets -------------------------------------------------------------
    fifo = d / "fifo.npz"
    os.mkfifo(fifo)
    add(
        Case(
            "identify -o FIFO",
            ["identify", str(good), "-o", str(fifo), "--levels", "11"],
            special=[fifo],
        )
    )
    if os.geteuid() == 0:
        null = d / "null"
        os.mknod(null, stat.S_IFCHR | 0o666, os.makedev(1, 3))  # a /dev/null of our own
        add(
            Case(
                "identify -o device node (root)",
                ["identify", str(good), "-o", str(null), "--levels", "11"],
                special=[null],
            )
        )
    add(Case("identify -o directory", ["identify", str(good), "-o", str(out), "--levels", "11"]))
    add(Case("identify -o missing folder", ["identify", str(good), "-o", str(d / "no" / "m.npz")]))
    target = w("target.npz", model.read_bytes())
    link = d / "link.npz"
    link.symlink_to(target)

    def link_kept() -> str:
        return "" if link.is_symlink() else "the symlink was replaced"

    add(
        Case(
            "identify -o symlink",
            ["identify", str(good), "-o", str(link), "--levels", "11"],
            valid=True,
            check=link_kept,
        )
    )
    # ---- full disk (file size limit) with existing outputs ---------------------------------
    old_model = d / "old_model.npz"
    PreisachModel.builtin(levels=5).save(old_model)
    old_json = w("old.json", '{"old": true}\n')
    add(
        Case(
            "identify -o EXISTING on a full disk",
            ["identify", str(good), "-o", str(old_model), "--levels", "101", "--method", "lsq"],
            fsize=20_000,
            keep=[old_model],
            folder=d,
        )
    )
    add(
        Case(
            "identify --json EXISTING on a full disk",
            [
                "identify",
                str(good),
                "-o",
                str(out / "m3.npz"),
                "--levels",
                "11",
                "--json",
                str(old_json),
            ],
            fsize=1_500,
            keep=[old_json],
            folder=d,
        )
    )
    aug_old = d / "aug_old.npz"
    from preisach.diagnose.augmented import AugmentedModel

    AugmentedModel(PreisachModel.builtin(levels=5), []).save(aug_old)
    add(
        Case(
            "diagnose --save-model EXISTING on a full disk",
            [
                "diagnose",
                "ss15-1hz",
                str(good),
                "--json",
                str(out / "d2.json"),
                "--save-model",
                str(aug_old),
                "--candidates",
                "delay",
            ],
            fsize=30_000,
            keep=[aug_old],
            folder=d,
        )
    )
    add(
        Case(
            "experiment --json EXISTING on a full disk",
            [
                "experiment",
                "drift",
                "--model",
                "ss15-1hz",
                "--seeds",
                "2",
                "--gains",
                "0.8",
                "--states",
                "n",
                "--json",
                str(old_json),
            ],
            fsize=200,
            keep=[old_json],
            folder=d,
        )
    )
    # ---- bad options ------------------------------------------------------------------------
    for argv in (
        ["experiment", "drift", "--gains", "-1", "--json", str(out / "e.json")],
        ["experiment", "closed-loop", "--kp", "-100", "--json", str(out / "e.json")],
        ["experiment", "closed-loop", "--ki", "nan", "--json", str(out / "e.json")],
        ["experiment", "drift", "--model", str(empty_model), "--json", str(out / "e.json")],
        ["demo", "--seeds", "1", "-o", str(out / "demo")],
        ["nosuchcommand"],
        [],
    ):
        add(Case(" ".join(argv[:3]) or "no command", argv))
    # ---- memory -----------------------------------------------------------------------------
    add(
        Case(
            "diagnose beyond the memory budget",
            ["diagnose", "ss15-1hz", str(good), "--json", str(out / "d3.json")],
            env={"PREISACH_MEMORY_LIMIT": "0.0001"},
        )
    )
    # ---- trials -----------------------------------------------------------------------------
    tdir = d / "trials"
    tdir.mkdir()

    def trial(name: str, steps: str, device: str = "") -> Path:
        p = tdir / name
        p.write_text(TRIAL_HEAD.format(device=device) + steps)
        return p

    three = trial("three.toml", '[[steps]]\nkind = "hold"\nduration = 0.05\nvalue = 5.0\n' * 3)
    one = trial("one.toml", '[[steps]]\nkind = "hold"\nname = "only"\nduration = 0.05\n')
    long = trial("long.toml", '[[steps]]\nkind = "hold"\nduration = 60.0\nvalue = 20.0\n')
    bad_model = trial(
        "bad_model.toml", '[[steps]]\nkind = "hold"\nduration = 0.1\n', 'model = "ss15-3hz"'
    )
    add(Case("trial check unknown model", ["check", str(bad_model)], module="preisach.trials"))
    add(
        Case(
            "trial run unknown model",
            ["run", str(bad_model), "-o", str(tdir / "bm")],
            module="preisach.trials",
            check=lambda: "empty folder left" if (tdir / "bm").exists() else "",
        )
    )
    add(
        Case(
            "trial check broken TOML",
            ["check", str(w("broken.toml", "[trial\nx = "))],
            module="preisach.trials",
        )
    )
    r1 = tdir / "r1"
    add(
        Case(
            "trial run",
            ["run", str(three), "-o", str(r1), "-q"],
            valid=True,
            module="preisach.trials",
        )
    )
    snapshot: dict[str, bytes] = {}

    def snap() -> str:
        snapshot.update({p.name: p.read_bytes() for p in r1.iterdir()})
        return ""

    def same() -> str:
        now = {p.name: p.read_bytes() for p in r1.iterdir()}
        return "" if now == snapshot else "the refused folder was modified"

    add(Case("(snapshot)", ["check", str(three)], valid=True, module="preisach.trials", check=snap))
    add(
        Case(
            "trial run into a used folder",
            ["run", str(three), "-o", str(r1), "-q"],
            module="preisach.trials",
            check=same,
        )
    )

    def only_new() -> str:
        names = sorted(p.name for p in r1.iterdir())
        return "" if names == ["01_only.csv", "summary.json"] else f"old files left: {names}"

    add(
        Case(
            "trial run --overwrite with fewer steps",
            ["run", str(one), "-o", str(r1), "-q", "--overwrite"],
            valid=True,
            module="preisach.trials",
            check=only_new,
        )
    )
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        o = tdir / f"sig_{sig.name}"
        add(
            Case(
                f"trial run, {sig.name}",
                ["run", str(long), "-o", str(o), "-q", "--realtime"],
                module="preisach.trials",
                signal_after=(sig, o / "01_hold.csv", 200),
                trial_out=o,
            )
        )
    o = tdir / "full"
    add(
        Case(
            "trial run --realtime on a full disk",
            ["run", str(long), "-o", str(o), "-q", "--realtime"],
            module="preisach.trials",
            fsize=64_000,
            trial_out=o,
            folder=o,
        )
    )
    add(
        Case(
            "diagnose, Ctrl-C",
            ["diagnose", "ss15-1hz", str(good), "--json", str(out / "d4.json")],
            signal_after=(signal.SIGINT, None, 15.0),
        )
    )
    add(
        Case(
            "demo, Ctrl-C",
            ["demo", "-o", str(out / "demo2"), "-q"],
            signal_after=(signal.SIGINT, None, 15.0),
            folder=out,
        )
    )
    add(
        Case(
            "demo, SIGTERM",
            ["demo", "-o", str(out / "demo3"), "-q"],
            signal_after=(signal.SIGTERM, None, 15.0),
            folder=out,
        )
    )
    return cases


def main() -> int:
    """Run the matrix and print the counts."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", help="work in this folder and keep it")
    args = ap.parse_args()
    d = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="fault-matrix-"))
    d.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    counts: Counter[str] = Counter()
    try:
        for c in build_cases(d):
            kind, detail = run_case(c)
            if c.name.startswith("("):  # a helper step (the snapshot of a folder), not a case
                continue
            counts[kind] += 1
            print(f"{kind:<13} {c.name:<48} {detail}", flush=True)
    finally:
        if not args.keep:
            shutil.rmtree(d, ignore_errors=True)
    total = sum(counts.values())
    print(
        f"\n{total} inputs and faults tried in {time.monotonic() - t0:.0f} s: "
        + ", ".join(
            f"{counts[k]} {k}"
            for k in (
                "clear error",
                "accepted",
                "traceback",
                "misleading",
                "data lost",
                "left driving",
            )
        )
    )
    return 0 if counts["traceback"] + counts["data lost"] + counts["left driving"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
