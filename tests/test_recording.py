"""Tests of the recording format: CSV/NPZ reader and writer, streaming writer."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from preisach.errors import PreisachWarning, RecordingFormatError
from preisach.recording import Recording, RecordingWriter, as_recordings, recording_labels

# ----------------------------------------------------------------------------- helpers


def bits(a: np.ndarray) -> np.ndarray:
    """Bit patterns, so that -0.0 != 0.0 and any last-digit change is caught."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def assert_identical(a: Recording, b: Recording) -> None:
    assert a.column_names == b.column_names
    for (name, x), y in zip(a.to_dict().items(), b.to_dict().values()):
        assert x.dtype == np.float64 and y.dtype == np.float64, name
        np.testing.assert_array_equal(bits(x), bits(y), err_msg=name)
    assert a.metadata == b.metadata
    for key, value in a.metadata.items():
        assert type(b.metadata[key]) is type(value), key


def awkward_recording(n: int = 200) -> Recording:
    """Values whose decimal text is long or unusual, to prove the round trip is exact."""
    rng = np.random.default_rng(1234)
    t = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, n))  # non-uniform, not decimal-friendly
    u = rng.normal(0.0, 50.0, n)
    y = rng.normal(0.0, 1e-3, n)
    u[:6] = [1 / 3, -0.0, 5e-324, 1e300, -1.7976931348623157e308, 0.1 + 0.2]
    y[:3] = [2.0**-1074, 123456789012345678.0, 1e-5]
    return Recording.from_arrays(
        t=t,
        u=u,
        y=y,
        sample_time=1e-3,
        experiment="fod_sweep",
        metadata={
            "n_cycles": 12,
            "gain": -2.5e-3,
            "amplifier.serial": "007",  # numeric-looking string must stay a str
            "note": "ratio 3:1, # not a comment",
            "padded": "  spaces  ",
            "multi": "line one\nline two",
            "quoted": '"already quoted"',
            "empty": "",
            "unicode": "µm/V",
            "big_int": 2**70,
            "fit_error": float("inf"),
        },
        temp=rng.normal(25.0, 0.1, n),
        u_cmd=u * 0.999,
    )


def write(path: Path, text: str) -> Path:
    path.write_bytes(text.encode("utf-8"))
    return path


HEADER = "# sample_time: 0.001\n# experiment: unit\nt,u,y\n"  # data rows start at line 4


def load_error(tmp_path: Path, text: str, name: str = "rec.csv") -> str:
    path = write(tmp_path / name, text)
    with pytest.raises(RecordingFormatError) as info:
        Recording.load(path)
    assert isinstance(info.value, ValueError)
    msg = str(info.value)
    assert name in msg
    return msg


# ----------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".CSV"])
def test_round_trip_is_bit_exact(tmp_path: Path, suffix: str) -> None:
    rec = awkward_recording()
    path = tmp_path / f"rec{suffix}"
    rec.save(path)
    back = Recording.load(path)
    assert_identical(rec, back)
    assert back == rec
    assert list(back.columns) == ["temp", "u_cmd"]
    # save again from the loaded copy: still identical
    path2 = tmp_path / f"rec2{suffix}"
    back.save(path2)
    assert_identical(rec, Recording.load(path2))


def test_round_trip_empty_recording(tmp_path: Path) -> None:
    rec = Recording.from_arrays(u=[], y=[], sample_time=0.01, extra=[])
    for suffix in (".csv", ".npz"):
        rec.save(tmp_path / f"e{suffix}")
        back = Recording.load(tmp_path / f"e{suffix}")
        assert len(back) == 0 and back.column_names == ("t", "u", "y", "extra")
        assert back == rec


def test_csv_layout_is_readable(tmp_path: Path) -> None:
    rec = Recording.from_arrays(
        u=[0.0, 0.5, 1.0],
        y=[-1.25, -1.2, 2.0],
        sample_time=0.001,
        experiment="demo",
        u_cmd=[1, 2, 3],
    )
    rec.save(tmp_path / "r.csv")
    assert (tmp_path / "r.csv").read_text(encoding="utf-8") == (
        "# sample_time: 0.001\n"
        "# input_units: V\n"
        "# output_units: V\n"
        "# experiment: demo\n"
        "t,u,y,u_cmd\n"
        "0.0,0.0,-1.25,1.0\n"
        "0.001,0.5,-1.2,2.0\n"
        "0.002,1.0,2.0,3.0\n"
    )
    assert not list(tmp_path.glob(".*tmp")), "temporary file left behind"


def test_save_rejects_unknown_suffix(tmp_path: Path) -> None:
    rec = Recording.from_arrays(u=[1.0], y=[2.0], sample_time=1.0)
    with pytest.raises(ValueError, match="'.txt'"):
        rec.save(tmp_path / "r.txt")
    with pytest.raises(RecordingFormatError, match=r"r\.txt.*'\.txt'"):
        Recording.load(write(tmp_path / "r.txt", "t,u,y\n"))


# ----------------------------------------------------------------------------- reading CSV


def test_metadata_parsing(tmp_path: Path) -> None:
    path = write(
        tmp_path / "m.csv",
        "# sample_time: 0.0005\n"
        "# input_units: V\n"
        "#output_units:V\n"
        "# experiment: fod sweep 3\n"
        "# n_cycles: 12\n"
        "# gain: -2.5e-3\n"
        "# offset: +4\n"
        "# note: ratio 3:1\n"
        '# serial: "0042"\n'
        "# missing: nan\n"
        "\n"
        "t,u,y\n"
        "0,1,2\n"
        "0.0005,1,2\n",
    )
    rec = Recording.load(path)
    assert rec.metadata == {
        "sample_time": 0.0005,
        "input_units": "V",
        "output_units": "V",
        "experiment": "fod sweep 3",
        "n_cycles": 12,
        "gain": -2.5e-3,
        "offset": 4,
        "note": "ratio 3:1",
        "serial": "0042",
        "missing": rec.metadata["missing"],
    }
    assert np.isnan(rec.metadata["missing"])
    assert type(rec.metadata["n_cycles"]) is int
    assert type(rec.metadata["offset"]) is int
    assert type(rec.metadata["sample_time"]) is float
    assert rec.sample_time == 0.0005


def test_extra_columns_kept_in_file_order_any_column_order(tmp_path: Path) -> None:
    path = write(
        tmp_path / "x.csv",
        "y, temp ,t,u,u_cmd\n10,25.5,0.0,1,-1\n20,25.25,0.1,2,-2\n30,25.0,0.2,3,-3\n",
    )
    rec = Recording.load(path)
    np.testing.assert_array_equal(rec.t, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(rec.u, [1, 2, 3])
    np.testing.assert_array_equal(rec.y, [10, 20, 30])
    assert list(rec.columns) == ["temp", "u_cmd"]
    np.testing.assert_array_equal(rec.columns["temp"], [25.5, 25.25, 25.0])
    np.testing.assert_array_equal(rec.columns["u_cmd"], [-1, -2, -3])
    assert rec.metadata == {}


def test_crlf_bom_and_trailing_blank_lines(tmp_path: Path) -> None:
    text = "\ufeff# experiment: win\r\nt,u,y\r\n0,1,2\r\n1,3,4\r\n\r\n\r\n"
    rec = Recording.load(write(tmp_path / "w.csv", text))
    assert rec.metadata == {"experiment": "win"}
    np.testing.assert_array_equal(rec.y, [2, 4])


def test_no_row_is_dropped(tmp_path: Path) -> None:
    n = 5000
    body = "".join(f"{i * 0.001!r},{i},{-i}\n" for i in range(n))
    rec = Recording.load(write(tmp_path / "many.csv", HEADER + body))
    assert len(rec) == n
    np.testing.assert_array_equal(rec.u, np.arange(n))
    np.testing.assert_array_equal(rec.y, -np.arange(n))


def test_trailing_comment_lines_are_merged_into_metadata(tmp_path: Path) -> None:
    text = (
        "# experiment: trial\n# operator: a\nt,u,y\n0,1,2\n1,2,3\n"
        "# end_status: complete\n\n# operator: b\n# rows: 2\n"
    )
    rec = Recording.load(write(tmp_path / "tr.csv", text))
    assert len(rec) == 2
    assert rec.metadata == {
        "experiment": "trial",
        "operator": "b",
        "end_status": "complete",
        "rows": 2,
    }


# ----------------------------------------------------------------------------- CSV errors


def test_error_not_a_number_names_line_and_column(tmp_path: Path) -> None:
    msg = load_error(tmp_path, HEADER + "0,1,2\n0.001,1,2\n0.002,1,abc\n0.003,1,2\n")
    assert "rec.csv line 6, column 'y': 'abc' is not a number" in msg


def test_error_empty_field_and_underscore_number(tmp_path: Path) -> None:
    msg = load_error(tmp_path, HEADER + "0,1,2\n0.001,,2\n")
    assert "line 5, column 'u': '' is not a number" in msg
    msg = load_error(tmp_path, HEADER + "0,1_000,2\n")
    assert "line 4, column 'u': '1_000' is not a number" in msg


def test_error_missing_required_columns_named_and_found_listed(tmp_path: Path) -> None:
    msg = load_error(tmp_path, "# sample_time: 1\ntime,u,x\n0,1,2\n")
    assert "line 2" in msg
    assert "missing required column(s) 't', 'y'" in msg
    assert "'time', 'u', 'x'" in msg


def test_error_wrong_number_of_fields(tmp_path: Path) -> None:
    msg = load_error(tmp_path, HEADER + "0,1,2\n0.001,1,2,3\n")
    assert "rec.csv line 5: expected 3 fields (t,u,y) but found 4" in msg
    msg = load_error(tmp_path, HEADER + "0,1\n")
    assert "line 4: expected 3 fields" in msg and "found 2" in msg


@pytest.mark.parametrize("bad_t", ["0.001", "0.0005"])
def test_error_non_monotonic_time_names_first_offending_line(tmp_path: Path, bad_t: str) -> None:
    rows = f"0,1,2\n0.001,1,2\n{bad_t},1,2\n0.0001,1,2\n"
    msg = load_error(tmp_path, HEADER + rows)
    assert "rec.csv line 6, column 't'" in msg
    assert "row index 2" in msg
    assert "strictly increasing" in msg


@pytest.mark.parametrize(
    ("row", "column", "shown"),
    [("0.002,nan,2", "u", "nan"), ("0.002,1,inf", "y", "inf"), ("0.002,1,-Infinity", "y", "-inf")],
)
def test_error_nan_inf_names_line_and_column(
    tmp_path: Path, row: str, column: str, shown: str
) -> None:
    msg = load_error(tmp_path, HEADER + f"0,1,2\n0.001,1,2\n{row}\n0.003,1,nan\n")
    assert f"rec.csv line 6, column '{column}': {shown} is not finite" in msg


def test_error_nan_in_extra_column(tmp_path: Path) -> None:
    msg = load_error(tmp_path, "t,u,y,temp\n0,1,2,3\n1,1,2,NaN\n")
    assert "line 3, column 'temp'" in msg


def test_error_comment_in_middle_of_data_names_the_line(tmp_path: Path) -> None:
    msg = load_error(tmp_path, HEADER + "0,1,2\n# paused: yes\n0.001,1,2\n")
    assert "rec.csv line 5: comment line in the middle of the data" in msg
    assert "line 6" in msg


def test_error_blank_line_in_middle_of_data(tmp_path: Path) -> None:
    msg = load_error(tmp_path, HEADER + "0,1,2\n0.001,1,2\n\n0.002,1,2\n")
    assert "rec.csv line 6: blank line in the middle of the data" in msg


def test_error_malformed_metadata_lines(tmp_path: Path) -> None:
    msg = load_error(tmp_path, "# sample_time: 1\n# just a remark\nt,u,y\n")
    assert "line 2" in msg and "'# key: value'" in msg
    msg = load_error(tmp_path, "# bad key: 1\nt,u,y\n")
    assert "line 1" in msg and "'bad key'" in msg
    msg = load_error(tmp_path, "# a: 1\n# a: 2\nt,u,y\n")
    assert "line 2" in msg and "'a' appears twice" in msg
    msg = load_error(tmp_path, "t,u,y\n0,1,2\n# end: 1\n# bad trailer\n")
    assert "line 4" in msg and "'# key: value'" in msg


def test_error_header_problems(tmp_path: Path) -> None:
    msg = load_error(tmp_path, "# a: 1\n0,1,2\n")
    assert "line 2" in msg and "'0'" in msg and "not a valid column name" in msg
    msg = load_error(tmp_path, "t,u,y,\n")
    assert "line 1" in msg and "empty column name at position 4" in msg
    msg = load_error(tmp_path, "t,u,y,u\n")
    assert "duplicate column name(s) 'u'" in msg
    msg = load_error(tmp_path, "# sample_time: 1\n\n")
    assert "no header row" in msg
    msg = load_error(tmp_path, "")
    assert "no header row" in msg


def test_error_invalid_utf8_names_line(tmp_path: Path) -> None:
    path = tmp_path / "rec.csv"
    path.write_bytes(b"t,u,y\n0,1,2\n1,\xff,2\n")
    with pytest.raises(RecordingFormatError, match=r"rec\.csv line 3: not valid UTF-8"):
        Recording.load(path)


def test_missing_file_is_not_a_format_error(tmp_path: Path) -> None:
    for name in ("nope.csv", "nope.npz"):
        with pytest.raises(FileNotFoundError):
            Recording.load(tmp_path / name)


# ----------------------------------------------------------------------------- truncated files


def test_truncated_last_line_is_dropped_with_warning(tmp_path: Path) -> None:
    # killed mid-write: the last row was cut off after '1.2' and has no newline
    text = HEADER + "0,1,2\n0.001,1,2\n0.002,1,2\n0.003,1.2"
    path = write(tmp_path / "cut.csv", text)
    with pytest.warns(PreisachWarning, match=r"cut\.csv line 7.*no trailing newline"):
        rec = Recording.load(path)
    assert len(rec) == 3
    np.testing.assert_array_equal(rec.t, [0, 0.001, 0.002])
    assert "end_status" not in rec.metadata


def test_complete_last_line_is_kept_without_warning(tmp_path: Path) -> None:
    # filterwarnings=error: any warning here fails the test
    rec = Recording.load(write(tmp_path / "ok.csv", HEADER + "0,1,2\n0.001,1,2\n"))
    assert len(rec) == 2


def test_only_the_last_line_may_be_dropped(tmp_path: Path) -> None:
    # a bad line followed by a newline is an error, not a silently dropped row
    msg = load_error(tmp_path, HEADER + "0,1,2\n0.001,1.2\n")
    assert "line 5: expected 3 fields" in msg
    # a bad complete line before a truncated last line is still an error
    path = write(tmp_path / "rec.csv", HEADER + "0,x,2\n0.001,1")
    with pytest.raises(RecordingFormatError, match="line 4, column 'u'"):
        Recording.load(path)


def test_truncated_trailer_comment_is_dropped_with_warning(tmp_path: Path) -> None:
    path = write(tmp_path / "c.csv", HEADER + "0,1,2\n# end_sta")
    with pytest.warns(PreisachWarning, match="line 5"):
        rec = Recording.load(path)
    assert len(rec) == 1 and "end_status" not in rec.metadata


# ----------------------------------------------------------------------------- NPZ


def save_npz(path: Path, **arrays: object) -> Path:
    with open(path, "wb") as f:
        np.savez(f, **arrays)
    return path


def test_npz_without_metadata_entry_loads(tmp_path: Path) -> None:
    path = save_npz(
        tmp_path / "p.npz", t=np.arange(3), u=np.ones(3), y=np.zeros(3, np.float32), w=[1, 2, 3]
    )
    rec = Recording.load(path)
    assert rec.metadata == {} and list(rec.columns) == ["w"]
    assert rec.t.dtype == np.float64 and rec.y.dtype == np.float64


def test_npz_errors(tmp_path: Path) -> None:
    def err(**arrays: object) -> str:
        path = save_npz(tmp_path / "rec.npz", **arrays)
        with pytest.raises(RecordingFormatError) as info:
            Recording.load(path)
        assert "rec.npz" in str(info.value)
        return str(info.value)

    t = np.arange(4.0)
    assert "missing required column(s) 'y'; found 't', 'u'" in err(t=t, u=t)
    assert "column 'y', index 2: nan is not finite" in err(t=t, u=t, y=[0, 1, np.nan, 3])
    assert "column 't', index 3" in err(t=[0, 1, 2, 1.5], u=t, y=t)
    assert "column 'u': has 3 samples but column 't' has 4" in err(t=t, u=t[:3], y=t)
    assert "column 'u': expected a 1-D array" in err(t=t, u=np.ones((4, 1)), y=t)
    assert "column 'u': dtype <U1" in err(t=t, u=np.array(list("abcd")), y=t)
    assert "entry '__metadata__'" in err(t=t, u=t, y=t, __metadata__=np.array("{not json"))
    assert "bool" in err(t=t, u=t, y=t, __metadata__=np.array('{"flag": true}'))

    junk = write(tmp_path / "junk.npz", "this is not a zip archive\n")
    with pytest.raises(RecordingFormatError, match=r"junk\.npz: not a readable NPZ"):
        Recording.load(junk)


# ----------------------------------------------------------------------------- Recording API


def test_from_arrays_builds_time_from_sample_time() -> None:
    rec = Recording.from_arrays(
        u=[0, 1, 2, 3], y=[4, 5, 6, 7], sample_time=0.25, experiment="x", u_cmd=[1, 1, 1, 1]
    )
    np.testing.assert_array_equal(rec.t, [0.0, 0.25, 0.5, 0.75])
    assert rec.t.dtype == rec.u.dtype == rec.columns["u_cmd"].dtype == np.float64
    assert rec.metadata == {
        "sample_time": 0.25,
        "input_units": "V",
        "output_units": "V",
        "experiment": "x",
    }
    assert len(rec) == 4
    assert rec.sample_time == 0.25
    assert rec.duration == 0.75


def test_from_arrays_validation() -> None:
    with pytest.raises(ValueError, match="t .s. or sample_time"):
        Recording.from_arrays(u=[1.0], y=[1.0])
    with pytest.raises(TypeError, match="requires both u"):
        Recording.from_arrays(t=[0.0], u=[1.0])
    with pytest.raises(ValueError, match="positive"):
        Recording.from_arrays(u=[1.0], y=[1.0], sample_time=0.0)
    with pytest.raises(ValueError, match="'y' has 2"):
        Recording.from_arrays(t=[0, 1, 2], u=[1, 2, 3], y=[1, 2])
    with pytest.raises(ValueError, match=r"t\[2\]"):
        Recording.from_arrays(t=[0, 1, 1], u=[1, 2, 3], y=[1, 2, 3])
    with pytest.raises(ValueError, match="'u' has the non-finite value nan at index 1"):
        Recording.from_arrays(t=[0, 1], u=[1, np.nan], y=[1, 2])
    with pytest.raises(TypeError, match="bool"):
        Recording.from_arrays(u=[1.0], y=[1.0], sample_time=1.0, metadata={"closed_loop": True})
    with pytest.raises(ValueError, match="clashes"):
        Recording(t=[0.0], u=[1.0], y=[1.0], columns={"u": [2.0]})


def test_sample_time_falls_back_to_median_diff() -> None:
    rec = Recording.from_arrays(t=[0.0, 0.1, 0.2, 0.35, 0.45], u=np.zeros(5), y=np.zeros(5))
    assert "sample_time" not in rec.metadata
    assert rec.sample_time == pytest.approx(0.1)
    assert rec.duration == pytest.approx(0.45)
    with pytest.raises(ValueError, match="sample_time is unknown"):
        _ = Recording.from_arrays(t=[0.0], u=[0.0], y=[0.0]).sample_time


def test_slice_half_open_split_covers_every_sample_once() -> None:
    n = np.arange(10.0)
    rec = Recording.from_arrays(u=n, y=-n, sample_time=0.1, experiment="s", c=2 * n)
    first, second = rec.slice(None, 0.5), rec.slice(0.5, None)
    np.testing.assert_array_equal(first.u, [0, 1, 2, 3, 4])
    np.testing.assert_array_equal(second.u, [5, 6, 7, 8, 9])
    np.testing.assert_array_equal(second.t, rec.t[5:])  # times are not shifted
    np.testing.assert_array_equal(second.columns["c"], [10, 12, 14, 16, 18])
    assert len(first) + len(second) == len(rec)
    assert second.metadata == rec.metadata and second.metadata is not rec.metadata
    mid = rec.slice(0.25, 0.55)
    np.testing.assert_array_equal(mid.u, [3, 4, 5])
    assert len(rec.slice(0.31, 0.32)) == 0
    assert rec.slice() == rec
    # a copy, not a view
    second.u[0] = 99.0
    assert rec.u[5] == 5.0
    with pytest.raises(ValueError, match="before start"):
        rec.slice(0.5, 0.2)


def test_to_dict_and_equality() -> None:
    rec = Recording.from_arrays(u=[1.0, 2.0], y=[3.0, 4.0], sample_time=1.0, w=[5.0, 6.0])
    d = rec.to_dict()
    assert list(d) == ["t", "u", "y", "w"]
    np.testing.assert_array_equal(d["w"], [5.0, 6.0])
    other = Recording.from_arrays(u=[1.0, 2.0], y=[3.0, 4.5], sample_time=1.0, w=[5.0, 6.0])
    assert rec != other
    assert "n=2" in repr(rec)


# ----------------------------------------------------------------------------- streaming writer


def test_writer_appends_flushes_and_closes(tmp_path: Path) -> None:
    path = tmp_path / "trial.csv"
    rng = np.random.default_rng(7)
    t = np.arange(30) * 1e-3 + 1e-4 * rng.random(30)
    u, y, c = rng.normal(size=(3, 30))
    meta = {"sample_time": 1e-3, "input_units": "V", "output_units": "V", "experiment": "loop"}
    with RecordingWriter(path, columns=("t", "u", "y", "u_cmd"), metadata=meta, fsync=False) as w:
        assert Recording.load(path).metadata == meta  # header on disk before any data
        assert w.append({"t": t[:10], "u": u[:10], "y": y[:10], "u_cmd": c[:10]}) == 10
        # flushed: another reader sees every row while the writer is still open
        mid = Recording.load(path)
        np.testing.assert_array_equal(bits(mid.y), bits(y[:10]))
        assert "end_status" not in mid.metadata
        w.append(np.column_stack([t[10:29], u[10:29], y[10:29], c[10:29]]))
        w.append([t[29], u[29], y[29], c[29]])  # a single row
        w.append({"t": [], "u": [], "y": [], "u_cmd": []})
        assert w.n_rows == 30 and not w.closed
    assert w.closed and w.status == "complete"
    rec = Recording.load(path)
    assert rec.metadata == {**meta, "end_status": "complete"}
    for name, ref in (("t", t), ("u", u), ("y", y)):
        np.testing.assert_array_equal(bits(getattr(rec, name)), bits(ref))
    np.testing.assert_array_equal(bits(rec.columns["u_cmd"]), bits(c))
    assert path.read_text(encoding="utf-8").endswith("\n# end_status: complete\n")


def test_writer_fsync_flag(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []
    real_fsync = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (calls.append(fd), real_fsync(fd))[1])
    with RecordingWriter(tmp_path / "a.csv") as w:  # fsync=True by default
        n0 = len(calls)
        w.append({"t": [0.0], "u": [1.0], "y": [2.0]})
        w.append({"t": [1.0], "u": [1.0], "y": [2.0]})
        assert len(calls) == n0 + 2
    calls.clear()
    with RecordingWriter(tmp_path / "b.csv", fsync=False) as w:
        w.append({"t": [0.0], "u": [1.0], "y": [2.0]})
    assert calls == []


def test_writer_exception_sets_aborted_status_and_keeps_rows(tmp_path: Path) -> None:
    path = tmp_path / "abort.csv"
    with pytest.raises(RuntimeError, match="sensor timeout"):
        with RecordingWriter(path, metadata={"experiment": "x"}, fsync=False) as w:
            w.append({"t": [0.0, 0.1], "u": [1.0, 2.0], "y": [3.0, 4.0]})
            raise RuntimeError("sensor timeout")
    rec = Recording.load(path)
    assert rec.metadata["end_status"] == "aborted: RuntimeError: sensor timeout"
    np.testing.assert_array_equal(rec.u, [1.0, 2.0])


def test_writer_multiline_exception_message_round_trips(tmp_path: Path) -> None:
    path = tmp_path / "abort2.csv"
    with pytest.raises(ValueError):
        with RecordingWriter(path, fsync=False):
            raise ValueError("first\nsecond")
    assert Recording.load(path).metadata["end_status"] == "aborted: ValueError: first\nsecond"


def test_writer_keyboard_interrupt_status(tmp_path: Path) -> None:
    path = tmp_path / "int.csv"
    with pytest.raises(KeyboardInterrupt):
        with RecordingWriter(path, fsync=False) as w:
            w.append({"t": [0.0], "u": [1.0], "y": [2.0]})
            raise KeyboardInterrupt
    rec = Recording.load(path)
    assert rec.metadata["end_status"] == "interrupted"
    assert len(rec) == 1


def test_writer_rejects_bad_chunks_without_writing(tmp_path: Path) -> None:
    path = tmp_path / "v.csv"
    w = RecordingWriter(path, fsync=False)
    w.append({"t": [0.0, 1.0], "u": [0.0, 0.0], "y": [0.0, 0.0]})
    with pytest.raises(ValueError, match=r"row 1, column 'y': nan is not finite"):
        w.append({"t": [2.0, 3.0], "u": [0.0, 0.0], "y": [0.0, np.nan]})
    with pytest.raises(ValueError, match=r"row 0, column 't'.*last time written"):
        w.append({"t": [1.0], "u": [0.0], "y": [0.0]})
    with pytest.raises(ValueError, match=r"row 2, column 't'"):
        w.append({"t": [2.0, 3.0, 3.0], "u": [0, 0, 0], "y": [0, 0, 0]})
    with pytest.raises(ValueError, match=r"missing \['y'\], unknown \['z'\]"):
        w.append({"t": [5.0], "u": [0.0], "z": [0.0]})
    with pytest.raises(ValueError, match="different lengths"):
        w.append({"t": [5.0, 6.0], "u": [0.0], "y": [0.0]})
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        w.append(np.zeros((2, 4)))
    assert w.n_rows == 2
    w.close(status="done", metadata={"trials": 1})
    w.close(status="ignored")  # second close does nothing
    with pytest.raises(ValueError, match="closed"):
        w.append({"t": [9.0], "u": [0.0], "y": [0.0]})
    rec = Recording.load(path)
    assert len(rec) == 2
    assert rec.metadata == {"trials": 1, "end_status": "done"}


def test_writer_constructor_checks(tmp_path: Path) -> None:
    existing = write(tmp_path / "old.csv", "t,u,y\n0,1,2\n")
    with pytest.raises(FileExistsError):
        RecordingWriter(existing)
    assert existing.read_text() == "t,u,y\n0,1,2\n"  # never clobbered
    with RecordingWriter(existing, overwrite=True, fsync=False):
        pass
    assert len(Recording.load(existing)) == 0
    with pytest.raises(ValueError, match="missing 'y'"):
        RecordingWriter(tmp_path / "a.csv", columns=("t", "u"))
    with pytest.raises(ValueError, match="reserved"):
        RecordingWriter(tmp_path / "b.csv", metadata={"end_status": "x"})
    with pytest.raises(ValueError, match="duplicate"):
        RecordingWriter(tmp_path / "c.csv", columns=("t", "u", "y", "u"))
    assert not (tmp_path / "a.csv").exists() and not (tmp_path / "b.csv").exists()


def test_killed_writer_file_loads_every_complete_row(tmp_path: Path) -> None:
    """A real process appends chunks and dies with os._exit: no close, no buffer flush."""
    import preisach

    path = tmp_path / "killed.csv"
    script = textwrap.dedent(
        f"""
        import os
        import numpy as np
        from preisach.recording import RecordingWriter
        w = RecordingWriter({str(path)!r}, metadata={{"experiment": "killed"}}, fsync=False)
        for k in range(5):
            t = np.arange(k * 100, (k + 1) * 100) * 1e-3
            w.append({{"t": t, "u": np.sin(t), "y": np.cos(t)}})
        os._exit(3)
        """
    )
    pkg_parent = str(Path(preisach.__file__).resolve().parent.parent)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([*(p for p in sys.path if p), pkg_parent])
    proc = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True)
    assert proc.returncode == 3, proc.stderr
    rec = Recording.load(path)
    assert len(rec) == 500
    assert rec.metadata == {"experiment": "killed"}  # no end_status: it never closed
    t = np.arange(500) * 1e-3
    np.testing.assert_array_equal(rec.t, t)
    np.testing.assert_array_equal(rec.y, np.cos(t))


def test_killed_writer_mid_row_simulated(tmp_path: Path) -> None:
    """The writer's file as a kill in the middle of a write leaves it."""
    path = tmp_path / "mid.csv"
    with RecordingWriter(path, metadata={"sample_time": 0.5}, fsync=False) as w:
        w.append({"t": [0.0, 0.5, 1.0], "u": [1.0, 2.0, 3.0], "y": [4.0, 5.0, 6.0]})
    text = path.read_text(encoding="utf-8")
    assert text.endswith("# end_status: complete\n")
    cut = text[: text.index("# end_status")] + "1.5,4.0,7."  # status never written, row cut
    write(path, cut)
    with pytest.warns(PreisachWarning, match=r"mid\.csv line 6"):
        rec = Recording.load(path)
    np.testing.assert_array_equal(rec.y, [4.0, 5.0, 6.0])
    assert rec.metadata == {"sample_time": 0.5}


# ----------------------------------------------------------------------------- as input


def test_as_recordings_accepts_every_kind_and_labels_by_one_rule(tmp_path: Path) -> None:
    from types import SimpleNamespace

    t = np.arange(5) * 1e-3
    named = Recording.from_arrays(t, t, 2 * t, experiment="wipe")
    by_name = Recording.from_arrays(t, t, t, metadata={"name": "n1", "experiment": ""})
    path = tmp_path / "from_file.csv"
    Recording.from_arrays(t, -t, t).save(path)
    duck = SimpleNamespace(t=t, u=t, y=3 * t, metadata={"experiment": "duck", "flag": True})
    recs = as_recordings([named, str(path), duck, by_name, Path(path)])
    assert all(isinstance(r, Recording) for r in recs)
    assert recs[0] is named  # passed through, not copied
    np.testing.assert_array_equal(recs[1].u, -t)
    np.testing.assert_array_equal(recs[2].y, 3 * t)
    assert recs[2].metadata == {"experiment": "duck"}  # the bool is not recording metadata
    assert recording_labels(recs) == ["wipe", "from_file #1", "duck", "n1", "from_file #2"]
    assert as_recordings(named) == [named]
    assert [len(r) for r in as_recordings(path)] == [5]
    assert as_recordings(r for r in (named,)) == [named]
    assert recording_labels([SimpleNamespace(t=t, u=t, y=t)] * 2) == ["recording 0", "recording 1"]
    assert recording_labels(recs[:2], ["a", "a"]) == ["a #1", "a #2"]


def test_as_recordings_errors_name_the_argument(tmp_path: Path) -> None:
    from types import SimpleNamespace

    with pytest.raises(ValueError, match="recordings: need at least one"):
        as_recordings([])
    with pytest.raises(TypeError, match=r"recordings\[1\]: expected a Recording"):
        as_recordings([Recording.from_arrays(u=[0.0, 1.0], y=[0.0, 1.0], sample_time=1.0), 3])
    with pytest.raises(TypeError, match="identification: expected"):
        as_recordings(np.zeros((3, 3)), argument="identification")
    with pytest.raises(ValueError, match=r"recordings\[0\]: t must be strictly increasing"):
        as_recordings([SimpleNamespace(t=[0.0, 0.0], u=[0.0, 1.0], y=[0.0, 1.0])])
    with pytest.raises(FileNotFoundError):
        as_recordings(tmp_path / "missing.csv")
    write(tmp_path / "bad.csv", "t,u\n0,1\n")
    with pytest.raises(RecordingFormatError, match="bad.csv"):
        as_recordings([tmp_path / "bad.csv"])
    with pytest.raises(ValueError, match="names: got 1 labels for 2"):
        recording_labels([object(), object()], ["a"], argument="names")
