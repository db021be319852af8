"""Small things users trip over: --version, a task far outside the others (a warning), a task
outside ``bounds`` (an error naming it)."""

from __future__ import annotations

import copy
import glob
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest
import yaml

import fleetctl
from fleetctl.cli import main
from fleetctl.mission import MissionError, load_mission
from fleetctl.mission.outliers import far_task_warnings, far_tasks
from planners.core.problem import Task

ROOT = Path(__file__).resolve().parents[1]
RECON = yaml.safe_load((ROOT / "missions" / "recon.yaml").read_text())


def _write(tmp_path: Path, d: dict[str, Any]) -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return path


def _with_far_task(position: list[float]) -> dict[str, Any]:
    d = copy.deepcopy(RECON)
    d["tasks"][4] = {"id": "t5", "position": position}  # a typo: 5200 instead of 52
    return d


def test_version_from_the_package_metadata() -> None:
    want = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    p = subprocess.run([sys.executable, "-m", "fleetctl.cli", "--version"], capture_output=True, text=True,
                       cwd=ROOT, timeout=60)
    assert p.returncode == 0 and p.stdout.strip() == f"fleetctl {want}"
    assert fleetctl.package_version() == want == fleetctl.__version__


def test_version_falls_back_to_the_module(monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib.metadata as md

    def missing(name: str) -> str:
        raise md.PackageNotFoundError(name)

    monkeypatch.setattr(md, "version", missing)
    assert fleetctl.package_version() == fleetctl.__version__


def test_plan_warns_about_a_task_far_outside_the_others(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, _with_far_task([5200, 85, 4]))
    assert main(["plan", "--mission", str(path), "--json"]) == 0
    err = capsys.readouterr().err.splitlines()
    warnings = [line for line in err if "warning" in line]
    assert len(warnings) == 1, err
    assert "task 't5'" in warnings[0] and "m from the centroid of the other tasks" in warnings[0]
    d = float(warnings[0].split(" is ")[1].split(" m ")[0])
    assert 5000 < d < 5200


def test_deploy_warns_too(tmp_path: Path) -> None:
    d = _with_far_task([5200, 85, 4])
    d["carrier"]["connection"] = "udp://127.0.0.1:9"  # nothing there: the warning comes before the connect
    path = _write(tmp_path, d)
    p = subprocess.run([sys.executable, "-m", "fleetctl.cli", "deploy", "--mission", str(path), "--yes",
                        "--headless", "--timeout", "0.5", "--runs", str(tmp_path / "runs")],
                       capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert "warning" in p.stderr and "task 't5'" in p.stderr, p.stderr


def test_no_warning_for_the_shipped_missions() -> None:
    for f in [ROOT / "missions" / "recon.yaml", *map(Path, glob.glob(str(ROOT / "missions/paper/*.yaml")))]:
        assert far_task_warnings(load_mission(f)) == [], f


def test_far_needs_both_the_factor_and_the_distance() -> None:
    near = [Task(f"t{i}", (float(i), 0.0, 0.0)) for i in range(5)]
    assert far_tasks([*near, Task("x", (150.0, 0.0, 0.0))]) == []  # 3 x far but < 200 m
    assert [t.id for t, _, _ in far_tasks([*near, Task("x", (400.0, 0.0, 0.0))])] == ["x"]
    spread = [Task(f"t{i}", (100.0 * i, 0.0, 0.0)) for i in range(5)]
    assert far_tasks([*spread, Task("x", (450.0, 0.0, 0.0))]) == []  # 250 m > 200 m but < 3 x 100 m
    two_sites = [Task(f"a{i}", (float(i), 0.0, 0.0)) for i in range(6)]
    two_sites += [Task(f"b{i}", (1000.0 + i, 0.0, 0.0)) for i in range(5)]
    assert far_tasks(two_sites) == []  # two clusters: neither is "outside the others"
    assert far_tasks([Task("a", (0.0, 0.0, 0.0)), Task("b", (5000.0, 0.0, 0.0))]) == []


def test_a_task_outside_bounds_is_an_error_naming_it(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    d = copy.deepcopy(RECON)
    d["bounds"] = [[-100, -100], [300, 250]]
    load_mission(_write(tmp_path, d))  # all inside
    d["tasks"][4] = {"id": "t5", "position": [5200, 85, 4]}
    with pytest.raises(MissionError, match=r"tasks\[4\]: task 't5' at \(5200, 85\) lies outside bounds"):
        load_mission(_write(tmp_path, d))
    assert main(["plan", "--mission", str(tmp_path / "m.yaml")]) == 2
    err = capsys.readouterr().err
    assert "task 't5'" in err and "outside bounds" in err and "Traceback" not in err


def test_a_closed_stdout_is_no_traceback() -> None:
    """`fleetctl plan --json | head -1`: the reader leaves early."""
    proc = subprocess.Popen([sys.executable, "-m", "fleetctl.cli", "plan", "--mission", "missions/recon.yaml",
                             "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # before the plan is printed (it is more than a pipe buffer's first write)
    err = proc.stderr.read().decode()
    assert proc.wait(60) == 141, err
    assert "Traceback" not in err


def test_the_command_line_loads_no_planner_or_heavy_library_before_it_needs_one() -> None:
    """``fleetctl plan`` starts in about the time Python imports NumPy: importing the
    command line and loading a mission import no planner (deployment, collection, roadmap, the
    teams' allocation), SciPy, shapely, matplotlib, rich, MAVLink, MQTT or asyncio; planning a
    deployment then loads the deployment planner and nothing of collection, roadmaps or SciPy."""
    code = ("import sys, fleetctl.cli\n"
            "from fleetctl.mission import load_mission\n"
            f"m = load_mission({str(ROOT / 'missions' / 'recon.yaml')!r})\n"
            "print(' '.join(sorted(sys.modules)))\n"
            "import planners\n"
            "planners.DEPLOY_PLANNERS['lee'](m.deploy_problem())\n"
            "print(' '.join(sorted(sys.modules)))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT, timeout=120).stdout.splitlines()
    loaded, planned = set(out[0].split()), set(out[1].split())
    heavy = ("scipy", "shapely", "matplotlib", "rich", "pymavlink", "paho", "aiomqtt", "aiohttp", "asyncio",
             "planners.deploy", "planners.collect", "planners.roadmap", "planners.teams.allocation")
    assert not {m for m in loaded if any(m == h or m.startswith(h + ".") for h in heavy)}
    assert "planners.deploy.lee" in planned
    unneeded = ("planners.collect", "planners.roadmap", "scipy", "shapely")
    assert not {m for m in planned if m.startswith(unneeded)}


def test_plan_shows_a_spinner_on_a_terminal_only(tmp_path: Path) -> None:
    """Planning a large mission takes seconds: a terminal's stderr says what is being planned; a pipe
    gets nothing but the result."""
    import os
    import pty

    argv = [sys.executable, "-m", "fleetctl.cli", "plan", "-m", str(ROOT / "missions" / "recon.yaml"),
            "--budget-ms", "300"]
    env = dict(os.environ, PYTHONPATH=str(ROOT), TERM="xterm")
    main_fd, tty_fd = pty.openpty()
    try:
        done = subprocess.run(argv, env=env, stdout=subprocess.PIPE, stderr=tty_fd, timeout=60)
        os.close(tty_fd)
        shown = b""
        while True:
            try:
                chunk = os.read(main_fd, 65536)
            except OSError:  # the terminal's other end is closed: everything is read
                break
            if not chunk:
                break
            shown += chunk
    finally:
        os.close(main_fd)
    assert done.returncode == 0
    assert b"planning 16 tasks with " in shown, shown[-500:]
    piped = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=60)
    assert piped.returncode == 0 and "planning" not in piped.stderr, piped.stderr
