"""Connection strings from MAVSDK, pymavlink and MAVProxy: mapped to fleetctl's spelling, or refused
with fleetctl's equivalent spelled out (docs/mavlink.md, "Connection strings")."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

from fleetctl.mavlink.link import parse_url
from fleetctl.mission import MissionError, load_mission
from fleetctl.mission.connections import ConnectionSpellingError, normalize_connection
from fleetctl.run.sim import sim_mission_dict

ROOT = Path(__file__).resolve().parents[2]

MAPPED = [
    ("udp://:14540", "udpin://0.0.0.0:14540"),  # MAVSDK: listen on every interface
    ("udpin://:14540", "udpin://0.0.0.0:14540"),  # MAVSDK 2
    ("udpin:0.0.0.0:14550", "udpin://0.0.0.0:14550"),  # pymavlink / MAVProxy
    ("udpout:10.0.0.2:14555", "udp://10.0.0.2:14555"),
    ("tcp:127.0.0.1:5760", "tcp://127.0.0.1:5760"),
    ("tcpout://10.0.0.2:5760", "tcp://10.0.0.2:5760"),  # MAVSDK 2
    ("serial:///dev/ttyUSB0:57600", "serial:///dev/ttyUSB0?baud=57600"),  # MAVSDK
    ("/dev/ttyACM0,57600", "serial:///dev/ttyACM0?baud=57600"),  # pymavlink / MAVProxy
    ("/dev/ttyACM0:921600", "serial:///dev/ttyACM0?baud=921600"),
    ("COM4,115200", "serial://COM4?baud=115200"),
    ("serial://COM3:57600", "serial://COM3?baud=57600"),
]
UNCHANGED = ["sim", "udp://127.0.0.1:14550", "udpout://10.0.0.2:14550", "udpin://0.0.0.0:14550",
             "tcp://127.0.0.1:5760", "serial:///dev/ttyACM0?baud=57600", "udp://[::1]:14550"]
REFUSED = [  # (what users write, what fleetctl tells them to write)
    ("tcpin://0.0.0.0:5760", "tcp://HOST:5760"),
    ("tcpin:0.0.0.0:5760", "udpin://0.0.0.0:5760"),
    ("udp:127.0.0.1:14550", "udpin://127.0.0.1:14550"),  # pymavlink's udp: listens
    ("udp://0.0.0.0:14540", "udpin://0.0.0.0:14540"),
    ("udpbcast:0.0.0.0:14550", "udpin://0.0.0.0:14550"),
    ("com3", "serial://COM3?baud=57600"),
    ("/dev/ttyUSB0", "serial:///dev/ttyUSB0?baud=57600"),
    ("serial:///dev/ttyUSB0", "serial:///dev/ttyUSB0?baud=57600"),
    ("tcp://:5760", "tcp://HOST:5760"),
]


@pytest.mark.parametrize(("given", "want"), MAPPED)
def test_unambiguous_spellings_are_mapped(given: str, want: str) -> None:
    assert normalize_connection(given) == want
    parse_url(want)  # the link takes the mapped form


@pytest.mark.parametrize("given", UNCHANGED)
def test_fleetctl_spellings_are_kept(given: str) -> None:
    assert normalize_connection(given) == given


@pytest.mark.parametrize(("given", "hint"), REFUSED)
def test_ambiguous_spellings_name_the_fleetctl_form(given: str, hint: str) -> None:
    with pytest.raises(ConnectionSpellingError, match=hint.replace("?", r"\?")):
        normalize_connection(given)


def _recon(tmp_path: Path, carrier: str, unit: str | None = None) -> Path:
    d = yaml.safe_load((ROOT / "missions" / "recon.yaml").read_text())
    d = copy.deepcopy(d)
    d["carrier"]["connection"] = carrier
    if unit is not None:
        d["rovers"].pop("fleet")
        d["rovers"]["units"] = [{"id": f"r{i}", "sysid": 10 + i, "connection": unit} for i in range(1, 19)]
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return path


def test_the_mission_file_takes_and_maps_them(tmp_path: Path) -> None:
    m = load_mission(_recon(tmp_path, "udpin:0.0.0.0:14550", unit="/dev/ttyACM0,57600"))
    assert m.carrier.connection == "udpin://0.0.0.0:14550"
    assert {u.connection for u in m.rovers.units} == {"serial:///dev/ttyACM0?baud=57600"}
    assert sim_mission_dict(m)["carrier"]["connection"] == "udpin://0.0.0.0:14550"  # fleetctl sim too


def test_the_mission_file_refuses_them_with_the_key_path(tmp_path: Path) -> None:
    with pytest.raises(MissionError) as e:
        load_mission(_recon(tmp_path, "tcpin://0.0.0.0:5760"))
    msg = str(e.value)
    assert "carrier.connection" in msg and "tcp://HOST:5760" in msg and "Traceback" not in msg
    assert len(msg) < 400
