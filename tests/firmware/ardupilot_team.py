"""An ArduPilot SITL team for the firmware tests: an ArduRover carrier and ArduCopter rovers sitting
on it (one home), all on one ground-station UDP port, and the fleetctl command line run against
them as a user runs it.

The firmware is found through ``FLEETCTL_ARDUPILOT_DIR`` (:func:`sitl.firmware.find_ardupilot`);
without it the tests skip with one line. Stock parameters (``default_params/*.parm``) unless a
test adds its own.
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import yaml

from sitl.firmware import ArduPilotBuild, FirmwareFleet, FirmwareVehicle, find_ardupilot

ORIGIN = (47.397742, 8.545594, 488.0)
HOME = (*ORIGIN, 0.0)
SPEEDUP = 4.0  # the firmware's clock rate (lockstep): fleetctl is told with --speedup
TASKS = (("t1", (20.0, 10.0, 6.0)), ("t2", (-15.0, 20.0, 8.0)), ("t3", (5.0, -25.0, 5.0)))
READY_TIMEOUT = 120.0  # wall s from start until every vehicle passes fleetctl's preflight
SKIP = "ArduPilot SITL not found: set FLEETCTL_ARDUPILOT_DIR to a folder with arducopter and ardurover"


def build() -> ArduPilotBuild:
    b = find_ardupilot()
    if b is None:
        pytest.skip(SKIP)
    return b


@dataclass
class Team:
    """A running firmware team, its mission file and where its runs go."""

    fleet: FirmwareFleet
    mission: Path
    runs: Path
    rovers: list[str]
    env: dict[str, str] = field(default_factory=dict)

    @property
    def tasks(self) -> dict[str, tuple[float, float, float]]:
        """The mission's tasks (id -> ENU position)."""
        m = yaml.safe_load(self.mission.read_text())
        return {t["id"]: tuple(t["position"]) for t in m["tasks"]}

    def fleetctl(self, *args: str, timeout: float = 240.0,
                 check: bool = False) -> subprocess.CompletedProcess[str]:
        """Run ``fleetctl ARGS --mission M`` (``--speedup`` where it applies) and return it."""
        argv = [sys.executable, "-m", "fleetctl.cli", *args]
        if args and args[0] in ("status", "deploy", "collect", "run"):
            argv += ["--mission", str(self.mission), "--speedup", f"{SPEEDUP:g}"]
        env = {**os.environ, "PYTHONUNBUFFERED": "1", **self.env}
        proc = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, env=env, check=False)
        if check and proc.returncode != 0:
            raise AssertionError(f"fleetctl {' '.join(args)} exited {proc.returncode}:\n"
                                 f"{proc.stdout[-3000:]}\n{proc.stderr[-2000:]}\n{self.firmware_tail()}")
        return proc

    def fly(self, command: str, *extra: str,
            timeout: float = 240.0) -> tuple[subprocess.CompletedProcess[str], dict[str, Any]]:
        """``fleetctl COMMAND --yes --headless --summary`` and the summary it wrote."""
        out = self.runs / f"{command}-{time.monotonic_ns()}.json"
        proc = self.fleetctl(command, "--yes", "--headless", "--runs", str(self.runs), "--summary", str(out),
                             *extra, timeout=timeout)
        summary = json.loads(out.read_text()) if out.exists() else {}
        return proc, summary

    def wait_ready(self, timeout: float = READY_TIMEOUT) -> None:
        """Poll ``fleetctl status`` until every vehicle passes the preflight (GPS, home, EKF)."""
        deadline = time.monotonic() + timeout
        last = None
        while time.monotonic() < deadline:
            last = self.fleetctl("status", "--timeout", "5", timeout=60)
            if last.returncode == 0:
                return
            time.sleep(2.0)
        raise AssertionError(f"the firmware team was not ready within {timeout:g} s:\n"
                             f"{last.stdout[-2000:] if last else ''}{last.stderr[-1500:] if last else ''}")

    def firmware_tail(self, lines: int = 5) -> str:
        out = []
        for v in self.fleet.vehicles:
            try:
                text = self.fleet.log(v.name).read_text(errors="replace").splitlines()[-lines:]
            except OSError:
                continue
            out.append(f"--- {v.name}: " + " | ".join(text))
        return "\n".join(out)


def random_tasks(seed: int, n: int = 3) -> tuple[tuple[str, tuple[float, float, float]], ...]:
    """``n`` tasks 15-30 m from the carrier in random directions, 3-10 m up, at least 8 m apart: a
    mission fleetctl has never seen (the seed is printed by the tests that use it)."""
    import math
    import random

    rng = random.Random(seed)
    out: list[tuple[str, tuple[float, float, float]]] = []
    while len(out) < n:
        r, a = rng.uniform(15.0, 30.0), rng.uniform(0.0, 2 * math.pi)
        p = (round(r * math.cos(a), 1), round(r * math.sin(a), 1), round(rng.uniform(3.0, 10.0), 1))
        if all(horizontal(p, q) >= 8.0 for _, q in out):
            out.append((f"t{len(out) + 1}", p))
    return tuple(out)


def mission_yaml(gcs_port: int, n_rovers: int, *,
                 tasks: Sequence[tuple[str, tuple[float, float, float]]] = TASKS,
                 extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """A mission for the team: tasks 20-30 m from the carrier, which starts where the rovers sit."""
    m: dict[str, Any] = {
        "name": "fw",
        "origin": {"lat": ORIGIN[0], "lon": ORIGIN[1], "alt": ORIGIN[2]},
        "carrier": {"id": "carrier", "connection": f"udpin://127.0.0.1:{gcs_port}", "sysid": 1,
                    "position": [0, 0], "heading_deg": 0, "max_speed": 2.0, "accel": 1.0, "turn_rate": 1.0,
                    "unload_time": 2.0, "load_time": 2.0},
        "rovers": {"max_speed": 5.0, "accel": 2.5, "deploy_range": 60.0, "endurance_range": 1200.0,
                   "reserve": 0.1, "fleet": {"count": n_rovers, "sysid_start": 11}},
        "tasks": [{"id": tid, "position": list(pos)} for tid, pos in tasks],
        "dwell": 5.0,
    }
    for key, value in (extra or {}).items():
        if isinstance(value, dict) and isinstance(m.get(key), dict):
            m[key] = {**m[key], **value}
        else:
            m[key] = value
    return m


@contextlib.contextmanager
def ardupilot_team(tmp_path: Path, *, n_rovers: int = 3, gcs_port: int = 14560, instance_base: int = 0,
                   mission: Mapping[str, Any] | None = None, params: Mapping[str, float] | None = None,
                   env: Mapping[str, str] | None = None, ready: bool = True,
                   gcs_serial: int = 0) -> Iterator[Team]:
    """Start the carrier and ``n_rovers`` copters on the carrier's home, write the mission, wait
    until fleetctl's preflight passes (``ready``); stop everything on exit."""
    b = build()
    rovers = [f"r{k + 1}" for k in range(n_rovers)]
    kw = {"params": dict(params or {}), "gcs_serial": gcs_serial}
    vehicles = [FirmwareVehicle("carrier", 1, "rover", HOME, **kw)]  # type: ignore[arg-type]
    vehicles += [FirmwareVehicle(r, 11 + k, "copter", HOME, **kw)  # type: ignore[arg-type]
                 for k, r in enumerate(rovers)]
    path = tmp_path / "mission.yaml"
    path.write_text(yaml.safe_dump(dict(mission or mission_yaml(gcs_port, n_rovers)), sort_keys=False))
    fleet = FirmwareFleet(b, vehicles, gcs_port=gcs_port, speedup=SPEEDUP, instance_base=instance_base,
                          workdir=tmp_path / "firmware")
    with fleet:
        team = Team(fleet, path, tmp_path / "runs", rovers, dict(env or {}))
        if ready:
            team.wait_ready()
        yield team


def journal(run_dir: Path) -> list[dict[str, Any]]:
    path = run_dir / "journal.jsonl"
    if not path.exists():
        return []
    rows = []
    for line in path.read_text().splitlines():
        with contextlib.suppress(json.JSONDecodeError):
            rows.append(json.loads(line))
    return rows


def run_dir_of(proc: subprocess.CompletedProcess[str]) -> Path:
    first = proc.stdout.splitlines()[0] if proc.stdout else ""
    assert first.startswith("run folder: "), proc.stdout[:500] + proc.stderr[-1000:]
    return Path(first.removeprefix("run folder: ").strip())


@dataclass
class Seen:
    """What one vehicle last reported to :func:`probe`."""

    enu: tuple[float, float, float] | None = None
    armed: bool | None = None
    custom_mode: int | None = None
    landed_state: int | None = None
    texts: list[str] = field(default_factory=list)


def kill_run_once_deployed(argv: list[str], env: Mapping[str, str] | None = None,
                           cwd: Path | None = None) -> str:
    """Start ``fleetctl run`` (``argv``) and SIGKILL it once it prints that every rover is at its task
    (the dwell begins): the controller dies with no records written on the way out. Returns its
    output up to then."""
    proc = subprocess.Popen(argv, cwd=cwd, env=None if env is None else dict(env), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            if "deployed" in line:  # every rover at its task, the dwell begins
                proc.kill()
                break
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == -9, "".join(lines)[-3000:]
    return "".join(lines)


def probe(port: int, seconds: float = 3.0, *, sysids: Sequence[int] = (),
          beat: bool = True) -> dict[int, Seen]:
    """Listen on the team's ground-station port (no controller running) for ``seconds``: each
    vehicle's last position (ENU metres from the origin, height above ground), armed state, mode
    and landed state. Sends a GCS heartbeat so ArduPilot keeps talking to this port (``beat``;
    without it, the vehicles' link-loss failsafe sees no ground station)."""
    import socket

    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    from fleetctl.geo import Origin, geodetic_to_local

    origin = Origin(*ORIGIN)
    mav = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    parsers: dict[Any, Any] = {}
    seen: dict[int, Seen] = {}
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", port))
        sock.settimeout(0.2)
        end = time.monotonic() + seconds
        last_beat = 0.0
        addrs: set[Any] = set()
        while time.monotonic() < end:
            if beat and time.monotonic() - last_beat > 0.5:
                last_beat = time.monotonic()
                hb = mav.heartbeat_encode(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID,
                                          0, 0, 0).pack(mav)
                for a in addrs:
                    sock.sendto(hb, a)
            try:
                data, addr = sock.recvfrom(65536)
            except TimeoutError:
                continue
            addrs.add(addr)
            parser = parsers.setdefault(addr, mavlink2.MAVLink(None))
            parser.robust_parsing = True
            for msg in parser.parse_buffer(data) or []:
                sid = msg.get_srcSystem()
                if sysids and sid not in sysids:
                    continue
                s = seen.setdefault(sid, Seen())
                kind = msg.get_type()
                if kind == "GLOBAL_POSITION_INT":
                    alt = origin.alt + msg.relative_alt / 1e3
                    s.enu = geodetic_to_local(msg.lat / 1e7, msg.lon / 1e7, alt, origin)
                elif kind == "HEARTBEAT" and msg.get_srcComponent() == 1:
                    s.armed = bool(msg.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)
                    s.custom_mode = msg.custom_mode
                elif kind == "EXTENDED_SYS_STATE":
                    s.landed_state = msg.landed_state
                elif kind == "STATUSTEXT":
                    s.texts.append(msg.text)
    return seen


def param_answered(port: int, sysid: int, key: bytes | None, name: str = "SYSID_THISMAV",
                   seconds: float = 3.0) -> bool:
    """Send PARAM_REQUEST_READ (signed with ``key``, or unsigned) to ``sysid`` through the team's
    port: does a PARAM_VALUE come back? (A vehicle enforcing signing ignores unsigned requests.)"""
    import socket

    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    mav = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.link_id = 7  # a stream of its own
        # an hour ahead: SITL run faster than real time dates its signing clock ahead of the wall
        # clock (GPS time), and a timestamp more than 60 s behind it would be refused for that alone
        mav.signing.timestamp = int((time.time() + 3600 - 1420070400) * 1e5)
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", port))
        sock.settimeout(0.2)
        end = time.monotonic() + seconds
        addr = None
        sent = 0.0
        while time.monotonic() < end:
            if addr is not None and time.monotonic() - sent > 0.5:
                sent = time.monotonic()
                sock.sendto(mav.param_request_read_encode(sysid, 1, name.encode(), -1).pack(mav), addr)
            try:
                data, frm = sock.recvfrom(65536)
            except TimeoutError:
                continue
            for msg in parser.parse_buffer(data) or []:
                if msg.get_srcSystem() != sysid:
                    continue
                addr = frm
                if msg.get_type() == "PARAM_VALUE" and msg.param_id.rstrip("\x00") == name:
                    return True
    return False


def horizontal(a: Sequence[float], b: Sequence[float]) -> float:
    return float(((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2) ** 0.5)


def set_param(port: int, sysid: int, name: str, value: float) -> float:
    """Set one parameter of ``sysid`` through the team's port (fleetctl's own PARAM_SET with
    read-back), with no controller running."""
    import asyncio

    from fleetctl.mavlink.link import Link
    from fleetctl.mavlink.params import set_param as set_vehicle_param
    from fleetctl.mavlink.vehicle import Vehicle

    async def go() -> float:
        async with Link(f"udpin://127.0.0.1:{port}") as link:
            v = Vehicle(link, sysid, name=f"sys{sysid}")
            await v.wait_heartbeat(10.0)
            return await set_vehicle_param(v, name, value)

    return asyncio.run(go())


def land_where_they_are(port: int, sysids: Sequence[int], timeout: float = 60.0) -> None:
    """Land the given vehicles where they hover (NAV_LAND through fleetctl's own Vehicle) and
    wait until each reports being on the ground and disarmed: rovers that wait for the collection
    on the ground (no battery spent waiting)."""
    import asyncio

    from fleetctl.mavlink.link import Link
    from fleetctl.mavlink.vehicle import Vehicle

    async def go() -> None:
        async with Link(f"udpin://127.0.0.1:{port}") as link:
            vehicles = [Vehicle(link, s, name=f"sys{s}") for s in sysids]
            for v in vehicles:
                await v.wait_heartbeat(10.0)
                await v.configure_streams()
            await asyncio.gather(*(v.land() for v in vehicles))
            def down(v: Vehicle) -> bool:
                return v.on_ground is True and not v.armed

            await asyncio.gather(*(v.wait_until(down, timeout, "landed") for v in vehicles))

    asyncio.run(go())
