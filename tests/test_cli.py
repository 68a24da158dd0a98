"""The preisach command line."""

import subprocess
import sys

import pytest

from preisach.cli import main


def test_demo_writes_figure_and_summary(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out)]) == 0
    fig = out / "major_loop_fod.png"
    assert fig.exists() and fig.stat().st_size > 10_000
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = (out / "summary.txt").read_text()
    for name in ("ss15-1hz", "ss15-2hz", "ss15-4hz"):
        assert name in text
    assert "y(u_max, u_max) = 3.4900 V" in text
    assert "non-negative (mu in Mp)" in text  # 1 Hz
    assert "4 negative nodes" in text         # 2 Hz, as section 3.3.3
    assert "wrote" in capsys.readouterr().out


def test_help_and_missing_command(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    assert "demo" in capsys.readouterr().out
    assert main([]) == 2


def test_console_script_entry_point():
    r = subprocess.run([sys.executable, "-m", "preisach.cli", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and "demo" in r.stdout
