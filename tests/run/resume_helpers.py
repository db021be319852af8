"""Helpers for the kill/resume tests (test_resume.py): a small mission on real UDP URLs, the
simulated fleet served by ``fleetctl sim`` in its own process, the controller (``fleetctl deploy``,
``run``, ``resume``) as a subprocess, polling its write-ahead journal for the moment to kill it,
the journal invariants a resumed run must keep, and a look at the simulated world through a
fresh MAVLink connection (what really flies, independent of the controller's records).

Every process started here has a timeout and is killed in a ``finally``.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from tests.run.ctl_helpers import free_udp_port, mission_dict, write_mission

ROOT = Path(__file__).resolve().parents[2]
ENV = os.environ | {"PYTHONPATH": str(ROOT)}  # this checkout, whatever fleetctl is installed
CLI = [sys.executable, "-m", "fleetctl.cli"]

SIM_SPEEDUP = 5.0  # the external sim's speedup; the controller's clock is then the wall clock
TASKS = ["t1", "t2", "t3", "t4"]
ROVERS = ["r1", "r2", "r3", "r4", "r5"]  # one spare
CTL_TIMEOUT = 90.0  # s: a whole deploy/run/resume of the small mission (it takes ~10-20 s)
POLL = 0.005  # s between looks at the journal
DECK_RADIUS = 1.5  # m: a landed rover this close (horizontally) to the carrier is on its deck
REACH = 1.5  # m: a rover this close (3D) to a task is on it (the controller uses 1 m)


# ---------------------------------------------------------------------------------------------------
# the mission
# ---------------------------------------------------------------------------------------------------

def resume_mission_dict(url: str, *, name: str = "resumetest") -> dict[str, Any]:
    """4 tasks, 5 rovers (one spare) on one UDP URL. The tasks lie 30-150 m east of the carrier's
    start in a zig-zag and ``deploy_range`` is 20 m, so the plan is 4 stops with one rover each,
    and the carrier drives ~30 m before the first launch (a window of ~1 s between the first
    ``plan`` record and the first ``launch`` at 5x)."""
    d = mission_dict(rovers=len(ROVERS), carrier_connection=url, speedup=SIM_SPEEDUP)
    d["name"] = name
    d["rovers"]["deploy_range"] = 20.0
    d["tasks"] = [{"id": "t1", "position": [45, 14, 4]}, {"id": "t2", "position": [80, -14, 4]},
                  {"id": "t3", "position": [115, 14, 5]}, {"id": "t4", "position": [150, -12, 4]}]
    d["links"] = {"heartbeat_timeout": 3.0}
    return d


def write_resume_mission(tmp_path: Path, name: str = "mission.yaml",
                         **kw: Any) -> tuple[Path, dict[str, Any]]:
    d = resume_mission_dict(f"udp://127.0.0.1:{free_udp_port()}", **kw)
    return write_mission(d, tmp_path / name), d


def task_positions(d: dict[str, Any]) -> dict[str, tuple[float, float, float]]:
    return {t["id"]: tuple(float(c) for c in t["position"]) for t in d["tasks"]}  # type: ignore[misc]


# ---------------------------------------------------------------------------------------------------
# processes
# ---------------------------------------------------------------------------------------------------

def _tail(path: Path, n: int = 3000) -> str:
    try:
        return path.read_text(encoding="utf-8", errors="replace")[-n:]
    except OSError:
        return "<no output>"


def _stop(proc: subprocess.Popen[bytes], sig: int = signal.SIGTERM, grace: float = 10.0) -> None:
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            proc.send_signal(sig)
        try:
            proc.wait(timeout=grace)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


@dataclass
class Sim:
    proc: subprocess.Popen[bytes]
    log: Path

    def output(self) -> str:
        return _tail(self.log)


@contextlib.contextmanager
def sim_process(mission: Path, log: Path, speedup: float = SIM_SPEEDUP,
                timeout: float = 30.0, vehicles: int = 1 + len(ROVERS)) -> Iterator[Sim]:
    """``fleetctl sim --mission M --speedup X`` in its own process, until it has printed the URL
    of every one of its ``vehicles``; stopped with SIGTERM (then killed) on the way out."""
    with open(log, "wb") as out:
        proc = subprocess.Popen([*CLI, "sim", "--mission", str(mission), "--speedup", str(speedup)],
                                stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, cwd=ROOT,
                                env=ENV)
        sim = Sim(proc, log)
        try:
            deadline = time.monotonic() + timeout
            while _tail(log, 100000).count("udp://") < vehicles:
                if proc.poll() is not None:
                    raise AssertionError(f"fleetctl sim exited ({proc.returncode}):\n{sim.output()}")
                if time.monotonic() > deadline:
                    raise AssertionError(f"fleetctl sim did not print its URLs in {timeout} s:\n"
                                         f"{sim.output()}")
                time.sleep(0.05)
            yield sim
        finally:
            _stop(proc)


class Ctl:
    """A controller command (``fleetctl deploy|run|resume ...``) in its own process, stdout and
    stderr together in ``log``."""

    def __init__(self, args: list[str], log: Path) -> None:
        self.args = args
        self.log = log
        self._out: IO[bytes] = open(log, "wb")  # noqa: SIM115 - closed in close()
        self.proc = subprocess.Popen([*CLI, *args], stdout=self._out, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, cwd=log.parent, env=ENV)

    def output(self) -> str:
        return _tail(self.log, 1_000_000)

    def tail(self) -> str:
        return _tail(self.log)

    def wait(self, timeout: float = CTL_TIMEOUT) -> int:
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=10)
            raise AssertionError(f"fleetctl {' '.join(self.args[:1])} did not end in {timeout} s "
                                 f"(killed):\n{self.tail()}") from None

    def kill9(self) -> int:
        self.proc.kill()
        return self.proc.wait(timeout=10)

    def signal(self, sig: int, timeout: float = 40.0) -> int:
        self.proc.send_signal(sig)
        return self.wait(timeout)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(timeout=10)
        self._out.close()


@contextlib.contextmanager
def controller(args: list[str], log: Path) -> Iterator[Ctl]:
    ctl = Ctl(args, log)
    try:
        yield ctl
    finally:
        ctl.close()


def run_ctl(args: list[str], log: Path, timeout: float = CTL_TIMEOUT) -> tuple[int, str]:
    """Run a controller command to its end: (exit status, its output)."""
    with controller(args, log) as ctl:
        rc = ctl.wait(timeout)
        return rc, ctl.output()


# ---------------------------------------------------------------------------------------------------
# the journal
# ---------------------------------------------------------------------------------------------------

Records = list[dict[str, Any]]


def journal_lines(run_dir: Path) -> list[str]:
    return (run_dir / "journal.jsonl").read_text(encoding="utf-8").splitlines()


def parse_journal_strict(run_dir: Path) -> Records:
    """Every line of the journal is a JSON object with a ``kind`` and a ``t`` (a record is written
    whole, in one write, so even ``kill -9`` leaves no half line)."""
    recs: Records = []
    for n, line in enumerate(journal_lines(run_dir), 1):
        try:
            rec = json.loads(line)
        except ValueError:
            raise AssertionError(f"journal line {n} is not JSON: {line[:300]!r}") from None
        assert isinstance(rec, dict) and isinstance(rec.get("kind"), str), f"line {n}: {line[:300]!r}"
        assert isinstance(rec.get("t"), int | float), f"line {n} has no unix time t: {line[:300]!r}"
        recs.append(rec)
    return recs


def _read_partial(path: Path) -> Records:
    """The whole lines of a journal being written (a line may be half written while we look)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return []
    recs: Records = []
    for line in text.split("\n")[:-1]:  # the part after the last newline may be half written
        with contextlib.suppress(ValueError):
            rec = json.loads(line)
            if isinstance(rec, dict):
                recs.append(rec)
    return recs


def wait_journal(ctl: Ctl, run_dir: Path, until: Callable[[Records], bool], what: str,
                 timeout: float = 60.0) -> Records:
    """Poll ``run_dir/journal.jsonl`` until ``until(records)``; fails when the controller exits
    first or after ``timeout`` s."""
    path = run_dir / "journal.jsonl"
    deadline = time.monotonic() + timeout
    while True:
        recs = _read_partial(path)
        if until(recs):
            return recs
        if ctl.proc.poll() is not None:
            raise AssertionError(f"the controller exited ({ctl.proc.returncode}) before {what}; "
                                 f"journal kinds {[r.get('kind') for r in recs][-30:]}:\n{ctl.tail()}")
        if time.monotonic() > deadline:
            raise AssertionError(f"no {what} in the journal after {timeout} s:\n{ctl.tail()}")
        time.sleep(POLL)


def of_kind(recs: Records, *kinds: str) -> Records:
    return [r for r in recs if r.get("kind") in kinds]


def tasks_reached(recs: Records) -> set[str]:
    return {r["task"] for r in of_kind(recs, "task_reached")}


def rovers_launched(recs: Records) -> dict[str, str]:
    """rover -> task of every ``rover_launched`` record."""
    return {r["vehicle"]: r["task"] for r in of_kind(recs, "rover_launched")}


def launch_violations(recs: Records) -> list[str]:
    """A rover launched (``launch`` or ``rover_launched``) again, or for another task, while it
    flew (after its ``rover_launched``, before a ``rover_loaded``); a task reached twice."""
    flying: dict[str, str] = {}
    problems: list[str] = []
    for i, r in enumerate(recs):
        kind, rid = r.get("kind"), r.get("vehicle")
        if kind in ("launch", "rover_launched"):
            if rid in flying:
                problems.append(f"record {i}: {kind} {rid} for {r.get('task')} while it flies to "
                                f"{flying[rid]}")
            if kind == "rover_launched":
                flying[rid] = r.get("task")
        elif kind == "rover_loaded":
            flying.pop(rid, None)
    reached = Counter(r.get("task") for r in of_kind(recs, "task_reached"))
    problems += [f"task {t} has {n} task_reached records" for t, n in reached.items() if n > 1]
    return problems


def kinds_summary(recs: Records) -> str:
    """The journal's interesting records, one per line (for assertion messages)."""
    keep = {"run", "resumed", "phase", "launch", "rover_launched", "task_reached", "stop_reached",
            "carrier_released", "rover_loaded", "interrupted", "error", "summary", "task_unserved",
            "task_timeout", "rover_failed", "rover_skipped", "hold"}
    out = []
    for r in recs:
        if r.get("kind") in keep:
            extra = {k: r[k] for k in ("vehicle", "task", "stop", "phase", "text", "found", "result")
                     if r.get(k) is not None}
            out.append(f"  {r['kind']} {extra}")
    return "\n".join(out[-60:])


def first_output_line_names(output: str, run_dir: Path) -> bool:
    lines = output.splitlines()
    if not lines or not lines[0].startswith("run folder: "):
        return False
    return Path(lines[0].removeprefix("run folder: ").strip()).resolve() == run_dir.resolve()


# ---------------------------------------------------------------------------------------------------
# the simulated world, seen through a fresh MAVLink connection
# ---------------------------------------------------------------------------------------------------

@dataclass
class Seen:
    enu: tuple[float, float, float] | None
    on_ground: bool | None
    armed: bool
    on_deck: bool
    mode: str | None


def observe_fleet(mission: Path, timeout: float = 8.0) -> dict[str, Seen]:
    """Every vehicle as its telemetry shows it now (a second GCS on the sim's links)."""
    return asyncio.run(_observe(mission, timeout))


async def _observe(mission_path: Path, timeout: float) -> dict[str, Seen]:
    from fleetctl.mavlink.fleet import connect_fleet
    from fleetctl.mission import load_mission

    mission = load_mission(mission_path)
    fleet = await connect_fleet(mission, None, timeout=timeout)
    try:
        async def telemetry(v: Any) -> None:
            with contextlib.suppress(TimeoutError):
                await v.wait_until(lambda v: v.position is not None and v.landed_state is not None,
                                   timeout, "telemetry")

        await asyncio.gather(*(telemetry(v) for v in fleet.vehicles.values()))
        await asyncio.sleep(0.3)  # a few more position updates
        c = fleet.carrier.enu
        out: dict[str, Seen] = {}
        for vid, v in fleet.vehicles.items():
            p = v.enu
            deck = (vid != fleet.carrier_id and bool(v.on_ground) and p is not None and c is not None
                    and math.hypot(p[0] - c[0], p[1] - c[1]) <= DECK_RADIUS)
            out[vid] = Seen(p, v.on_ground, bool(v.armed), deck, v.mode_firmware)
        return out
    finally:
        await fleet.close()


def describe(seen: dict[str, Seen]) -> str:
    return "\n".join(f"  {vid}: enu={tuple(round(c, 1) for c in s.enu) if s.enu else None} "
                     f"on_ground={s.on_ground} armed={s.armed} on_deck={s.on_deck} mode={s.mode}"
                     for vid, s in seen.items())


def airborne(seen: dict[str, Seen]) -> set[str]:
    return {vid for vid, s in seen.items() if vid in ROVERS and s.on_ground is False}


def on_deck(seen: dict[str, Seen]) -> set[str]:
    return {vid for vid, s in seen.items() if s.on_deck}


def rovers_on_tasks(seen: dict[str, Seen],
                    tasks: dict[str, tuple[float, float, float]]) -> dict[str, list[str]]:
    """task -> the rovers within :data:`REACH` of it."""
    return {t: [vid for vid in ROVERS if seen[vid].enu is not None and math.dist(seen[vid].enu, pos) <= REACH]
            for t, pos in tasks.items()}


def read_summary(run_dir: Path) -> dict[str, Any]:
    path = run_dir / "summary.json"
    assert path.exists(), f"no {path}"
    return json.loads(path.read_text(encoding="utf-8"))


class Problems:
    """Checks that do not stop at the first failure: every broken promise of a run is reported
    together (with the journal's story and what the world shows) by :meth:`assert_none`."""

    def __init__(self) -> None:
        self.found: list[str] = []
        self.prefix = ""  # put before the messages of the checks that follow

    def check(self, ok: object, message: str) -> bool:
        if not ok:
            self.found.append(self.prefix + message)
        return bool(ok)

    def assert_none(self, *context: str) -> None:
        if self.found:
            lines = "\n".join(f"- {m}" for m in self.found)
            raise AssertionError(f"{len(self.found)} problem(s):\n{lines}\n" + "\n".join(context))


__all__ = ["CTL_TIMEOUT", "ROOT", "ROVERS", "SIM_SPEEDUP", "TASKS", "Ctl", "Problems", "Records", "Seen",
           "airborne", "controller", "describe", "first_output_line_names", "journal_lines", "kinds_summary",
           "launch_violations", "observe_fleet", "of_kind", "on_deck", "parse_journal_strict", "read_summary",
           "resume_mission_dict", "rovers_launched", "rovers_on_tasks", "run_ctl", "sim_process",
           "task_positions", "tasks_reached", "wait_journal", "write_resume_mission"]
