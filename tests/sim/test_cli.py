"""``python -m sim``: bad input ends in one clear line and writes nothing."""

from __future__ import annotations

import socket
import subprocess
import sys

from sim.cli import main


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_missing_scenario_is_one_line_naming_the_file(tmp_path, capsys):
    missing = tmp_path / "nope.toml"
    rep = tmp_path / "r.json"
    assert main(["run", str(missing), "--report", str(rep)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope.toml" in err[0] and err[0].startswith("error:")
    assert not rep.exists()


def test_bad_points_are_refused(capsys):
    assert main(["serve", "--points", "40", "10", "--duration", "0.1"]) == 2
    assert "points" in capsys.readouterr().err


def test_controller_without_server_says_so(capsys):
    port = _free_port()
    assert main(["controller", "--port", str(port), "--connect-timeout", "0.5"]) == 1
    assert f"127.0.0.1:{port}" in capsys.readouterr().err


def test_module_entry_point_help():
    out = subprocess.run([sys.executable, "-m", "sim", "--help"], capture_output=True,
                         text=True, timeout=60, check=True).stdout
    for cmd in ("serve", "controller", "run"):
        assert cmd in out


def test_job_stage_log_writes_lines_only_off_a_terminal(capsys):
    """Off a terminal (a log file) the job says where it is, a line at each tenth of a
    stage (none as it starts: bad input then stays one line); on a terminal the bar does
    and the log says nothing."""
    import io

    from rich.console import Console

    from sim.job_cli import _StageLog

    log = _StageLog(Console(file=io.StringIO(), force_terminal=False), 0.0)
    for d in range(0, 101):
        log("predict 0", d, 100)
    log("verify", 0, 3)
    log("verify", 3, 3)
    lines = capsys.readouterr().err.splitlines()
    pred = [ln for ln in lines if "predict 0:" in ln]
    assert [ln.rsplit(" ", 1)[1] for ln in pred] == [f"{10 * k}/100" for k in range(1, 11)]
    assert [ln.rsplit(" ", 1)[1] for ln in lines if "verify:" in ln] == ["3/3"]
    tty = _StageLog(Console(file=io.StringIO(), force_terminal=True), 0.0)
    tty("predict 0", 50, 100)
    assert capsys.readouterr().err == ""
