"""The firmware launcher's command lines (no firmware needed: nothing is started)."""

from __future__ import annotations

from pathlib import Path

import pytest

from sitl.firmware import ArduPilotBuild, FirmwareFleet, FirmwareVehicle


def test_a_relative_work_folder_still_finds_the_parameter_file(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """Each firmware runs in its own folder: a parameter file named relative to the caller's
    folder would not be found there (ArduPilot SITL panics: "Failed to load defaults")."""
    monkeypatch.chdir(tmp_path)
    v = FirmwareVehicle("carrier", 1, "rover", (47.0, 8.0, 488.0, 0.0), params={"CRUISE_SPEED": 3.0})
    fleet = FirmwareFleet(ArduPilotBuild(tmp_path / "ardupilot"), [v], gcs_port=14650,
                          workdir=Path("runs/seed-1"))
    assert fleet.workdir == tmp_path / "runs" / "seed-1"
    wd = fleet.workdir / "carrier"
    wd.mkdir(parents=True)
    assert isinstance(fleet.build, ArduPilotBuild)
    argv = fleet._ardupilot_argv(fleet.build, v, wd)
    defaults = argv[argv.index("--defaults") + 1].split(",")
    assert all(Path(d).is_absolute() for d in defaults)
    assert (wd / "fleetctl.parm").read_text() == "CRUISE_SPEED 3\n"
