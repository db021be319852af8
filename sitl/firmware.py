"""Real autopilot firmware in software-in-the-loop: start and stop ArduPilot and PX4 SITL vehicles.

The simulated fleet of this package (:class:`sitl.SimFleet`) is MAVLink written by us; this module
starts the firmware operators fly instead, each vehicle a process of its own with the firmware's
own physics, all sending MAVLink 2 to one ground-station UDP port (the controller listens there
with ``udpin://127.0.0.1:PORT`` and tells the vehicles apart by system id)::

    from sitl.firmware import FirmwareFleet, FirmwareVehicle, find_ardupilot

    vehicles = [FirmwareVehicle("carrier", sysid=1, frame="rover", home=HOME),
                FirmwareVehicle("r1", sysid=11, frame="copter", home=HOME)]
    with FirmwareFleet(find_ardupilot(), vehicles, gcs_port=14550, speedup=4) as fleet:
        fleet.url        # "udpin://127.0.0.1:14550"
        fleet.kill("r1") # SIGKILL one vehicle (a rover lost in flight)

Where the binaries are: ``FLEETCTL_ARDUPILOT_DIR`` (a folder with ``arducopter``, ``ardurover``
and ``default_params/{copter,rover}.parm``) and ``FLEETCTL_PX4_DIR`` (a folder with ``bin/px4`` and
``etc/``); :func:`find_ardupilot` and :func:`find_px4` return None when they are not set or hold
no firmware.

Each process runs in its own working directory (the firmware writes its parameters, logs and
terrain there) and is stopped with SIGTERM, then SIGKILL.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

Frame = Literal["copter", "rover", "hexa"]
ARDUPILOT_ENV = "FLEETCTL_ARDUPILOT_DIR"
PX4_ENV = "FLEETCTL_PX4_DIR"
PX4_AIRFRAMES = {"copter": 10040, "hexa": 10044, "rover": 10045}
DISCARD_PORT = 9  # UDP "discard": where an unused SITL serial port sends
ARDUPILOT_MODELS = {"copter": "+", "hexa": "hexa", "rover": "rover"}


class FirmwareError(RuntimeError):
    """A firmware binary missing or a vehicle process that died on start."""


@dataclass(frozen=True)
class FirmwareVehicle:
    """One firmware vehicle: its name, MAVLink system id, airframe and home (lat, lon, AMSL alt,
    heading in compass degrees). ``params`` are set as defaults at boot (ArduPilot: an extra
    defaults file; PX4: ``PX4_PARAM_*`` variables); ``model`` overrides the physics model
    (ArduPilot ``--model``, e.g. ``JSON`` for an external physics process; PX4
    ``PX4_SIMULATOR``, e.g. ``rotorpy`` for an external one). ``gcs_serial`` is
    the ArduPilot serial port of the ground-station link: 0 (SERIAL0) is the channel ArduPilot
    trusts like a USB cable and takes unsigned messages on even when signing is set up; 1 is a
    telemetry radio's port, where signing is enforced."""

    name: str
    sysid: int
    frame: Frame
    home: tuple[float, float, float, float]
    params: Mapping[str, float] = field(default_factory=dict)
    model: str | None = None
    gcs_serial: int = 0


@dataclass(frozen=True)
class ArduPilotBuild:
    """An ArduPilot SITL build: ``arducopter``, ``ardurover`` and their stock default parameters."""

    root: Path

    @property
    def name(self) -> str:
        return "ardupilot"

    def binary(self, frame: Frame) -> Path:
        return self.root / ("ardurover" if frame == "rover" else "arducopter")

    def defaults(self, frame: Frame) -> Path:
        return self.root / "default_params" / ("rover.parm" if frame == "rover" else "copter.parm")


@dataclass(frozen=True)
class Px4Build:
    """A PX4 SITL build with SIH (physics inside the firmware): ``bin/px4`` and ``etc/``."""

    root: Path

    @property
    def name(self) -> str:
        return "px4"

    @property
    def binary(self) -> Path:
        return self.root / "bin" / "px4"


Build = ArduPilotBuild | Px4Build


def _root(env: Mapping[str, str] | None, name: str) -> Path | None:
    root = (env if env is not None else os.environ).get(name)
    return Path(root).resolve() if root else None


def find_ardupilot(env: Mapping[str, str] | None = None) -> ArduPilotBuild | None:
    """The ArduPilot build named by ``FLEETCTL_ARDUPILOT_DIR``, or None."""
    root = _root(env, ARDUPILOT_ENV)
    build = None if root is None else ArduPilotBuild(root)
    ok = build is not None and all(os.access(build.binary(f), os.X_OK) for f in ("copter", "rover"))
    return build if ok else None


def find_px4(env: Mapping[str, str] | None = None) -> Px4Build | None:
    """The PX4 build named by ``FLEETCTL_PX4_DIR``, or None."""
    root = _root(env, PX4_ENV)
    build = None if root is None else Px4Build(root)
    ok = build is not None and os.access(build.binary, os.X_OK) and (build.root / "etc").is_dir()
    return build if ok else None


class FirmwareFleet:
    """Firmware vehicles started together, all sending to one ground-station UDP port.

    A context manager: the processes start on entry and are stopped on exit. ``instance_base``
    keeps several fleets on one machine apart (ArduPilot's TCP and physics ports and PX4's lock
    files are per instance number)."""

    def __init__(self, build: Build, vehicles: Sequence[FirmwareVehicle], *, gcs_port: int,
                 speedup: float = 1.0, instance_base: int = 0, workdir: Path | None = None) -> None:
        if len({v.sysid for v in vehicles}) != len(vehicles):
            raise FirmwareError("every firmware vehicle needs its own system id")
        self.build = build
        self.vehicles = list(vehicles)
        self.gcs_port = gcs_port
        self.speedup = speedup
        self.instance_base = instance_base
        self._own_workdir = workdir is None
        # absolute: each firmware runs in its own folder and reads its parameter file from there
        self.workdir = (workdir or Path(tempfile.mkdtemp(prefix=f"fleetctl-{build.name}-"))).absolute()
        self.procs: dict[str, subprocess.Popen[bytes]] = {}

    @property
    def url(self) -> str:
        """The controller's connection string for every vehicle of this fleet."""
        return f"udpin://127.0.0.1:{self.gcs_port}"

    def instance(self, name: str) -> int:
        return self.instance_base + [v.name for v in self.vehicles].index(name)

    def log(self, name: str) -> Path:
        """The vehicle's console output (firmware messages, for a failed test's report)."""
        return self.workdir / name / "console.log"

    # -- start and stop -------------------------------------------------------------------------
    def start(self) -> FirmwareFleet:
        for v in self.vehicles:
            self.procs[v.name] = self._spawn(v)
        time.sleep(0.3)
        dead = [n for n, p in self.procs.items() if p.poll() is not None]
        if dead:
            self.stop()
            tails = "; ".join(f"{n}: {self._tail(n)}" for n in dead)
            raise FirmwareError(f"{self.build.name} SITL exited on start: {tails}")
        return self

    def _spawn(self, v: FirmwareVehicle) -> subprocess.Popen[bytes]:
        wd = self.workdir / v.name
        wd.mkdir(parents=True, exist_ok=True)
        if isinstance(self.build, ArduPilotBuild):
            argv, env = self._ardupilot_argv(self.build, v, wd), dict(os.environ)
        else:
            argv, env = self._px4_argv(self.build, v, wd)
        out = open(self.log(v.name), "wb")  # noqa: SIM115 - owned by the child for its lifetime
        try:
            return subprocess.Popen(argv, cwd=wd, env=env, stdin=subprocess.DEVNULL, stdout=out,
                                    stderr=subprocess.STDOUT, start_new_session=True)
        finally:
            out.close()

    def _ardupilot_argv(self, build: ArduPilotBuild, v: FirmwareVehicle, wd: Path) -> list[str]:
        defaults = str(build.defaults(v.frame))
        params = dict(v.params)
        if v.gcs_serial:
            params.setdefault(f"SERIAL{v.gcs_serial}_PROTOCOL", 2)  # MAVLink 2
        if params:
            extra = wd / "fleetctl.parm"
            extra.write_text("".join(f"{k} {val:g}\n" for k, val in params.items()))
            defaults += f",{extra}"
        lat, lon, alt, hdg = v.home
        return [str(build.binary(v.frame)), "-S", "-w", "--model", v.model or ARDUPILOT_MODELS[v.frame],
                "--speedup", f"{self.speedup:g}", "--instance", str(self.instance(v.name)),
                "--sysid", str(v.sysid), "--defaults", defaults,
                "--home", f"{lat:.7f},{lon:.7f},{alt:.2f},{hdg:g}",
                *_serials(v.gcs_serial, self.gcs_port), "--sim-address=127.0.0.1"]

    def _px4_argv(self, build: Px4Build, v: FirmwareVehicle, wd: Path) -> tuple[list[str], dict[str, str]]:
        lat, lon, alt, _hdg = v.home
        env = dict(os.environ)
        env.update({"PX4_SYS_AUTOSTART": str(PX4_AIRFRAMES[v.frame]), "PX4_SIMULATOR": v.model or "sihsim",
                    "PX4_HOME_LAT": f"{lat:.7f}", "PX4_HOME_LON": f"{lon:.7f}", "PX4_HOME_ALT": f"{alt:.2f}",
                    "PX4_PARAM_MAV_SYS_ID": str(v.sysid), "PX4_PARAM_SDLOG_BACKEND": "0",
                    "PX4_SIM_SPEED_FACTOR": f"{self.speedup:g}"})
        for name, val in v.params.items():
            env[f"PX4_PARAM_{name}"] = f"{val:g}"
        # PX4 sends to 14550 until a client speaks: the ground-station port is that one
        if self.gcs_port != 14550:
            raise FirmwareError("PX4 SITL sends its ground-station link to UDP port 14550: "
                                "use gcs_port=14550")
        inst = self.instance(v.name)
        with contextlib.suppress(FileNotFoundError):
            Path(f"/tmp/px4_lock-{inst}").unlink()
        argv = [str(build.binary), "-i", str(inst), "-d", "-w", str(wd), str(build.root / "etc")]
        return argv, env

    def alive(self, name: str) -> bool:
        p = self.procs.get(name)
        return p is not None and p.poll() is None

    def kill(self, name: str) -> None:
        """SIGKILL one vehicle's process: it falls silent at once, as a vehicle lost in flight."""
        p = self.procs.get(name)
        if p is not None and p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait(5)

    def stop(self) -> None:
        for p in self.procs.values():
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGTERM)
        deadline = time.monotonic() + 5.0
        for p in self.procs.values():
            try:
                p.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                p.wait(5)

    def cleanup(self) -> None:
        """Remove the working directory (when this fleet made it)."""
        if self._own_workdir:
            shutil.rmtree(self.workdir, ignore_errors=True)

    def _tail(self, name: str, lines: int = 3) -> str:
        try:
            text = self.log(name).read_text(errors="replace").strip().splitlines()
        except OSError:
            return "no output"
        return " | ".join(text[-lines:]) or "no output"

    def __enter__(self) -> FirmwareFleet:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _serials(gcs_serial: int, gcs_port: int) -> list[str]:
    """SITL serial options: the ground-station link on SERIAL``gcs_serial``. SERIAL0 must be given
    either way (left to its default TCP port, SITL waits for a connection before it starts): when
    the link is on another port, SERIAL0 sends to the discard port."""
    out = [f"--serial{gcs_serial}", f"udpclient:127.0.0.1:{gcs_port}"]
    if gcs_serial != 0:
        out = ["--serial0", f"udpclient:127.0.0.1:{DISCARD_PORT}", *out]
    return out


@contextlib.contextmanager
def firmware_fleet(build: Build, vehicles: Sequence[FirmwareVehicle],
                   **kwargs: object) -> Iterator[FirmwareFleet]:
    """:class:`FirmwareFleet` as a context manager that also removes its working directory."""
    fleet = FirmwareFleet(build, vehicles, **kwargs)  # type: ignore[arg-type]
    try:
        with fleet:
            yield fleet
    finally:
        fleet.cleanup()


__all__ = ["ARDUPILOT_ENV", "PX4_ENV", "ArduPilotBuild", "FirmwareError", "FirmwareFleet", "FirmwareVehicle",
           "Px4Build", "find_ardupilot", "find_px4", "firmware_fleet"]
