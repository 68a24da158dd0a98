"""Fault injection: full disks, signals, corrupt files, refused targets, fuzzed readers.

Full disks are emulated with a file-size limit (``RLIMIT_FSIZE``: ``write`` fails with EFBIG
once a file would grow past it, exactly where ENOSPC would) in a child process, or with a shim
that makes ``fsync`` fail with ENOSPC in this one; signals go to a child running
``preisach trial run`` on the virtual rig.  docs/RELIABILITY.md describes what is promised.
"""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import preisach
import pytest
from _trial_files import ANY_MISSED, SIM_HEAD, sim_head, start_realtime_run, wait_for_rows
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from preisach import PreisachModel, Recording
from preisach._io import atomic_write, write_json, write_text
from preisach.cli import EXIT_FAILED, EXIT_INTERNAL, main
from preisach.errors import PreisachWarning, RecordingFormatError, TrialFileError

resource = pytest.importorskip("resource")

PKG_PARENT = str(Path(preisach.__file__).resolve().parent.parent)
FUZZ = settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)

HEAD = SIM_HEAD + ANY_MISSED


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([PKG_PARENT, *(p for p in sys.path if p)])
    env["OPENBLAS_NUM_THREADS"] = "1"
    return env


def _limit_file_size(nbytes: int):
    def apply() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of death
        resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, resource.RLIM_INFINITY))

    return apply


def _python(code: str, *, fsize: int | None = None, timeout: float = 60):
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        env=_env(),
        capture_output=True,
        text=True,
        timeout=timeout,
        preexec_fn=None if fsize is None else _limit_file_size(fsize),
    )


def _files(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


# ------------------------------------------------------------------------------------------
# atomic writes
# ------------------------------------------------------------------------------------------
def test_full_disk_leaves_every_old_file_intact(tmp_path):
    """Models, augmented models, JSON reports: a failed write keeps the old file, no temp."""
    from preisach.diagnose.augmented import AugmentedModel

    small = PreisachModel.builtin(levels=5)
    small.save(tmp_path / "model.npz")
    AugmentedModel(small, []).save(tmp_path / "aug.npz")
    (tmp_path / "report.json").write_text('{"old": true}\n')
    before = _files(tmp_path)
    code = f"""
        import json
        from preisach import PreisachModel
        from preisach._io import write_json
        from preisach.diagnose.augmented import AugmentedModel
        big = PreisachModel.builtin(levels=120)           # ~115 kB of Everett values
        out = {{}}
        for name, save in [
            ("model.npz", big.save),
            ("aug.npz", AugmentedModel(big, []).save),
            ("report.json", lambda p: write_json(p, list(range(40000)))),  # how --json writes
        ]:
            try:
                save({str(tmp_path)!r} + "/" + name)
                out[name] = "written"
            except OSError as exc:
                out[name] = [exc.errno, str(exc)]
        print(json.dumps(out))
    """
    r = _python(code, fsize=32_000)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for name in ("model.npz", "aug.npz", "report.json"):
        assert out[name] != "written", name
        err, msg = out[name]
        assert err == errno.EFBIG and name in msg and "unchanged" in msg
    assert _files(tmp_path) == before  # old bytes, and no temporary file left beside them


def test_write_errors_name_the_file_and_errno(tmp_path, monkeypatch, capsys):
    """ENOSPC at fsync (where delayed allocation reports it): the CLI names file and errno."""
    rec = tmp_path / "rec.csv"
    u = np.concatenate([np.linspace(-100, 100, 200), np.linspace(100, -100, 200)])
    Recording.from_arrays(u=u, y=np.tanh(u / 50), sample_time=1e-3).save(rec)
    out_json = tmp_path / "exp.json"
    out_json.write_text("{}\n")

    def full(fd: int) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", full)
    code = main(["identify", str(rec), "-o", str(tmp_path / "m.npz"), "--levels", "11"])
    err = capsys.readouterr().err
    assert code == EXIT_FAILED
    assert "m.npz" in err and "[Errno 28]" in err and "Traceback" not in err
    assert not (tmp_path / "m.npz").exists()
    with pytest.raises(OSError) as exc:
        write_json(out_json, {"new": 1})
    assert exc.value.errno == errno.ENOSPC and exc.value.filename == str(out_json)
    assert out_json.read_text() == "{}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exp.json", "rec.csv"]


def test_refuses_non_regular_targets_and_keeps_symlinks(tmp_path):
    rec = Recording.from_arrays(u=np.zeros(5), y=np.zeros(5), sample_time=1e-3)
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    with pytest.raises(OSError, match="FIFO") as exc:
        rec.save(fifo)
    assert exc.value.errno == errno.EINVAL and fifo.is_fifo()
    d = tmp_path / "dir.json"
    d.mkdir()
    with pytest.raises(IsADirectoryError):
        write_text(d, "x")
    target = tmp_path / "real.csv"
    rec.save(target)
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    Recording.from_arrays(u=np.ones(7), y=np.ones(7), sample_time=1e-3).save(link)
    assert link.is_symlink() and len(Recording.load(target)) == 7
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "dir.json",
        "fifo.csv",
        "link.csv",
        "real.csv",
    ]


def test_a_failing_producer_leaves_the_old_file(tmp_path):
    p = tmp_path / "f.txt"
    p.write_text("old")
    os.chmod(p, 0o640)

    def boom(f):
        f.write("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atomic_write(p, boom)
    assert p.read_text() == "old" and os.listdir(tmp_path) == ["f.txt"]
    write_text(p, "new")
    assert p.read_text() == "new" and (p.stat().st_mode & 0o777) == 0o640


# ------------------------------------------------------------------------------------------
# trials: output folders, signals, writer failures
# ------------------------------------------------------------------------------------------
def _trial(tmp_path: Path, steps: str, name: str = "t.toml") -> Path:
    p = tmp_path / name
    p.write_text(HEAD + steps)
    return p


def test_refused_folder_is_untouched_and_overwrite_keeps_only_the_new_run(tmp_path):
    from preisach.trials import run_trial_file

    three = _trial(tmp_path, '[[steps]]\nkind = "hold"\nduration = 0.05\nvalue = 5.0\n' * 3)
    out = tmp_path / "o"
    run_trial_file(three, out, fsync=False)
    (out / "notes.txt").write_text("mine")
    before = _files(out)
    with pytest.raises(FileExistsError, match="nothing was written"):
        run_trial_file(three, out, fsync=False)
    assert _files(out) == before
    one = _trial(tmp_path, '[[steps]]\nkind = "hold"\nname = "only"\nduration = 0.05\n', "one.toml")
    run_trial_file(one, out, overwrite=True, fsync=False)
    assert sorted(p.name for p in out.iterdir()) == ["01_only.csv", "notes.txt", "summary.json"]


def test_trial_check_rejects_what_run_rejects(tmp_path):
    from preisach.trials import check_trial

    p = tmp_path / "t.toml"
    p.write_text(
        sim_head(model="ss15-3hz") + ANY_MISSED + '[[steps]]\nkind = "hold"\nduration = 0.1\n'
    )
    with pytest.raises(TrialFileError, match="ss15-3hz.*neither a built-in model"):
        check_trial(p)
    assert main(["trial", "run", str(p), "-o", str(tmp_path / "o")]) == 1
    assert not (tmp_path / "o").exists()


def _start_trial(tmp_path: Path, *, fsize: int | None = None, value: float = 20.0):
    p = _trial(tmp_path, f'[[steps]]\nkind = "hold"\nduration = 60.0\nvalue = {value}\n')
    out = tmp_path / "o"
    limit = None if fsize is None else _limit_file_size(fsize)
    return start_realtime_run(p, out, env=_env(), preexec_fn=limit), out


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP], ids=lambda s: s.name)
def test_sigterm_and_sighup_stop_a_trial_like_ctrl_c(tmp_path, sig):
    if signal.getsignal(sig) is signal.SIG_IGN:  # e.g. under nohup; the trial inherits it
        pytest.skip(f"{sig.name} is ignored in this session: a trial rightly keeps ignoring it")
    proc, out = _start_trial(tmp_path)
    csv = out / "01_hold.csv"
    try:
        wait_for_rows(proc, csv, 200)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + sig, err
    assert f"stopped by {sig.name}" in err and "ramped to 0 V" in err and "Traceback" not in err
    rec = Recording.load(csv)  # finished: end_status written, no warning
    assert rec.metadata["end_status"] == "interrupted"
    assert rec.metadata["end_reason"] == f"stopped by {sig.name}"
    assert rec.u[-1] == 0.0 and np.max(np.abs(np.diff(rec.u))) <= 500.0 * 1e-3 + 1e-9
    summary = json.loads((out / "summary.json").read_text())
    assert summary["end_status"] == "interrupted" and summary["stop_signal"] == sig.name
    assert summary["final_output"] == 0.0
    assert sorted(p.name for p in out.iterdir()) == ["01_hold.csv", "summary.json"]


def test_a_failing_recording_stops_actuating_at_once(tmp_path):
    """The writer fails (file size limit, as on a full disk): stop, ramp, say why, exit 3."""
    t0 = time.monotonic()
    proc, out = _start_trial(tmp_path, fsize=64_000)
    try:
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    took = time.monotonic() - t0
    assert proc.returncode == EXIT_FAILED, err
    assert took < 20.0  # the waveform asks for 60 s; the old runner kept going
    assert "01_hold.csv" in err and "[Errno 27]" in err and "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["end_status"].startswith("aborted: OSError: [Errno 27]")
    assert "01_hold.csv" in summary["end_status"]
    assert summary["final_output"] == 0.0
    assert sorted(p.name for p in out.iterdir()) == ["01_hold.csv", "summary.json"]


def test_a_killed_trial_recording_loads_with_a_warning(tmp_path):
    p = tmp_path / "01_hold.csv"
    p.write_text(
        "# planned_samples: 1000\n# sample_time: 0.001\nt,u,y\n0.0,1.0,0.5\n0.001,1.0,0.5\n"
    )
    with pytest.warns(PreisachWarning, match="without end_status"):
        rec = Recording.load(p)
    assert len(rec) == 2


# ------------------------------------------------------------------------------------------
# command line: exit codes, one-line messages
# ------------------------------------------------------------------------------------------
def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and preisach.__version__ in capsys.readouterr().out


def test_internal_error_and_interrupt_exit_codes(tmp_path, capsys, monkeypatch):
    import importlib

    core = importlib.import_module("preisach.diagnose.core")  # the CLI imports diagnose from it

    model = tmp_path / "m.npz"
    PreisachModel.builtin(levels=11).save(model)
    rec = tmp_path / "r.csv"
    Recording.from_arrays(u=np.linspace(-100, 100, 100), y=np.zeros(100), sample_time=1e-3).save(
        rec
    )
    calls = []

    def interrupted(*a, **k):
        calls.append("ctrl-c")
        raise KeyboardInterrupt

    monkeypatch.setattr(core, "diagnose", interrupted)
    code = main(["diagnose", str(model), str(rec), "--json", str(tmp_path / "d.json")])
    err = capsys.readouterr().err
    assert calls and code == 130
    assert err.count("\n") == 1 and "interrupted" in err and "Traceback" not in err

    def bug(*a, **k):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(core, "diagnose", bug)
    assert (
        main(["diagnose", str(model), str(rec), "--json", str(tmp_path / "d.json")])
        == EXIT_INTERNAL
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "internal error" in err and "--debug" in err
    assert (
        main(["diagnose", str(model), str(rec), "--json", str(tmp_path / "d.json"), "--debug"])
        == EXIT_INTERNAL
    )
    assert "Traceback" in capsys.readouterr().err


def test_corrupt_and_swapped_model_files_are_clear_errors(tmp_path, capsys):
    from preisach.diagnose import load_model

    good = tmp_path / "good.npz"
    PreisachModel.builtin(levels=11).save(good)
    rec = tmp_path / "rec.csv"
    Recording.from_arrays(u=np.linspace(-100, 100, 50), y=np.zeros(50), sample_time=1e-3).save(rec)
    (tmp_path / "empty.npz").write_bytes(b"")
    (tmp_path / "trunc.npz").write_bytes(good.read_bytes()[:300])
    np.save(tmp_path / "array.npy", np.arange(3.0))
    for name in ("empty.npz", "trunc.npz", "array.npy", "rec.csv"):
        with pytest.raises(ValueError, match="not a") as exc:
            load_model(tmp_path / name)
        assert "pickle" not in str(exc.value) and name in str(exc.value)
        assert (
            main(["diagnose", str(tmp_path / name), str(rec), "--json", str(tmp_path / "d.json")])
            == 1
        )
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and name in err and "Traceback" not in err
    assert main(["verify", str(rec), str(good)]) == 1  # swapped arguments
    err = capsys.readouterr().err
    assert "pickle" not in err and "order of the arguments" in err


def test_simulate_with_a_state_name_is_a_clear_error():
    m = PreisachModel.builtin(levels=11)
    with pytest.raises(TypeError, match="state: expected a preisach.State"):
        m.simulate(np.zeros(3), state="negative")


def test_misleading_cases(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["identify", "--help"])
    assert exc.value.code == 0 and "%%" not in capsys.readouterr().out
    for argv in (["drift", "--gains", "-1"], ["closed-loop", "--kp", "-100"]):
        with pytest.raises(SystemExit) as exc:
            main(["experiment", *argv])
        assert exc.value.code == 2
        assert "must be" in capsys.readouterr().err
    from preisach.verify import congruency_metric

    u = np.linspace(-100, 100, 400)
    res = congruency_metric(Recording.from_arrays(u=u, y=np.tanh(u / 50), sample_time=1e-3))
    assert not res.pairs and "NOT TESTABLE" in res.table()


def test_memory_estimate_refuses_before_allocating(tmp_path, monkeypatch):
    from preisach.diagnose import diagnose
    from preisach.errors import ResourceLimitError

    monkeypatch.setenv("PREISACH_MEMORY_LIMIT", "0.001")  # 1 MiB
    n = 40_000
    t = np.arange(n) * 0.01
    u = 100 * np.sin(2 * np.pi * 0.5 * t)
    m = PreisachModel.builtin(levels=11)
    rec = Recording.from_arrays(u=u, y=m.simulate(u).output, sample_time=0.01)
    t0 = time.monotonic()
    with pytest.raises(ResourceLimitError, match="drift basis.*MiB"):
        diagnose(m, [rec])
    assert time.monotonic() - t0 < 20


# ------------------------------------------------------------------------------------------
# fuzzing the readers
# ------------------------------------------------------------------------------------------
@FUZZ
@given(data=st.binary(max_size=400))
def test_fuzz_model_npz_reader(tmp_path, data):
    from preisach.diagnose import load_model

    p = tmp_path / "f.npz"
    p.write_bytes(data)
    with pytest.raises(ValueError):
        load_model(p)


_VALID_NPZ = None


@FUZZ
@given(pos=st.integers(0, 10_000), byte=st.integers(0, 255), cut=st.integers(0, 10_000))
def test_fuzz_damaged_model_files(tmp_path, pos, byte, cut):
    global _VALID_NPZ
    if _VALID_NPZ is None:
        src = tmp_path / "src.npz"
        PreisachModel.builtin(levels=7).save(src)
        _VALID_NPZ = src.read_bytes()
    data = bytearray(_VALID_NPZ[: max(1, cut % (len(_VALID_NPZ) + 1))])
    data[pos % len(data)] = byte
    p = tmp_path / "f.npz"
    p.write_bytes(bytes(data))
    try:
        m = PreisachModel.load(p)
    except ValueError as exc:
        assert "pickle" not in str(exc)
    else:
        assert m.levels.size > 0


_CSV_CHARS = st.sampled_from(list('0123456789.,-+eE#: \ntuyabn_\r"') + ["nan", "inf", "1e400"])


@FUZZ
@given(text=st.lists(_CSV_CHARS, max_size=120).map("".join), prefix=st.booleans())
def test_fuzz_recording_csv_reader(tmp_path, text, prefix):
    p = tmp_path / "r.csv"
    p.write_text(("t,u,y\n" if prefix else "") + text)
    try:
        Recording.load(p)
    except RecordingFormatError:
        pass
    except PreisachWarning:  # filterwarnings=error: a cut-off last line, reported
        pass


@FUZZ
@given(data=st.binary(max_size=300))
def test_fuzz_recording_npz_reader(tmp_path, data):
    p = tmp_path / "r.npz"
    p.write_bytes(b"PK\x03\x04" + data)
    with pytest.raises(RecordingFormatError):
        Recording.load(p)


_TOML_VALUES = st.one_of(
    st.integers(-(10**20), 10**20),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
    st.booleans(),
    st.lists(st.one_of(st.integers(-300, 300), st.floats(-1e3, 1e3)), max_size=3),
)
_TOML_KEYS = st.sampled_from(
    [
        "sample_time",
        "kind",
        "model",
        "duration",
        "value",
        "range",
        "u_limits",
        "ramp_rate",
        "slew_rate",
        "levels",
        "frequency",
        "channel",
        "gain",
        "target",
        "y_d",
        "seed",
    ]
)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return (
            "nan"
            if v != v
            else ("inf" if v == float("inf") else "-inf" if v == -float("inf") else repr(v))
        )
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return str(v)


@pytest.mark.parametrize("step", ["kind = []", 'kind = "drive"\ntarget = ["psi_n"]\ny_d = 1.0'])
def test_trial_checker_names_a_list_where_a_word_belongs(tmp_path, step):
    # hypothesis found `kind = []` raising TypeError (a list cannot be looked up by name)
    from preisach.trials import check_trial

    p = tmp_path / "t.toml"
    p.write_text(HEAD + f"[[steps]]\n{step}\n")
    with pytest.raises(TrialFileError, match=r"steps\[0\]"):
        check_trial(p)


@FUZZ
@given(
    section=st.sampled_from(["trial", "device", "output", "input", "safety", "steps"]),
    items=st.dictionaries(_TOML_KEYS, _TOML_VALUES, max_size=4),
    kind=st.sampled_from(["hold", "fod_sweep", "noise", "pi", "drive", "initialise", "bogus"]),
)
def test_fuzz_trial_file_checker(tmp_path, section, items, kind):
    from preisach.trials import check_trial

    body = "\n".join(f"{k} = {_toml_value(v)}" for k, v in items.items())
    text = HEAD + f'[[steps]]\nkind = "{kind}"\nduration = 0.05\n'
    text += f"[[steps]]\n{body}\n" if section == "steps" else ""
    if section != "steps":
        text = (
            text.replace(f"[{section}]\n", f"[{section}]\n{body}\n", 1)
            if f"[{section}]\n" in text
            else text + f"\n[{section}]\n{body}\n"
        )
    p = tmp_path / "t.toml"
    p.write_text(text)
    try:
        check_trial(p)
    except TrialFileError:
        pass
