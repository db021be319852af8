"""The defaults docs/mission-file.md gives in words or formulas are what the loader does.

tests/docs/test_docs.py compares the literal defaults (`1.0`, `lee`, ...) with the loader's tables;
here every default the loader leaves to be worked out later (its table says None) is either
documented as absent (none, null, required, ...) or has a probe below that reads the numbers and
names out of the documented default and checks them against a loaded mission."""

from __future__ import annotations

import ast
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

import fleetctl.mission.schema as schema
from fleetctl.mavlink.fleet import fleet_urls
from fleetctl.mission import Mission
from fleetctl.mission.loader import parse_mission_text
from planners.core.problem import RoadmapParams
from tests.docs.test_docs import DOCS, _default_shown, _loader_specs

# a default cell that says the key has no value unless given (the loader keeps None)
ABSENT = re.compile(r"^(none\b|`null`|required\b|every vehicle|chosen by the client library|the system CAs"
                    r"|see `|as `carrier\.)")
BASE: dict[str, Any] = {
    "name": "defaults",
    "origin": {"lat": 47.0, "lon": 8.0, "alt": 400.0},
    "carrier": {"position": [0, 0], "max_speed": 10.0, "sysid": 3},
    "rovers": {"max_speed": 2.0, "deploy_range": 25.0},
    "tasks": [{"id": "t1", "position": [10, 0]}, {"id": "t2", "lat": 47.0001, "lon": 8.0001}],
}


def _load(**changes: Any) -> Mission:
    """BASE with top-level sections merged with ``changes`` (a None value removes the key)."""
    data = yaml.safe_load(yaml.safe_dump(BASE))
    for section, value in changes.items():
        if isinstance(value, dict) and isinstance(data.get(section), dict):
            data[section].update(value)
            data[section] = {k: v for k, v in data[section].items() if v is not None}
        else:
            data[section] = value
    return parse_mission_text(yaml.safe_dump(data), "defaults.yaml")


def _numbers(pattern: str, cell: str) -> list[float]:
    m = re.search(pattern, cell)
    assert m, f"the documented default {cell!r} no longer reads {pattern!r}: update this probe and the doc"
    return [float(g) for g in m.groups()]


def _takeoff_time(cell: str) -> None:
    height, again, settle = _numbers(
        r"^([\d.]+) m climbed from rest to rest at `climb_rate` and `accel` \(eq\. 4\.2; ([\d.]+) m / "
        r"`climb_rate` when `accel` is null\) \+ ([\d.]+) s", cell)
    assert again == height
    for climb in (0.5, 2.0):
        m = _load(rovers={"climb_rate": climb, "accel": None})
        assert m.rovers.takeoff_time == pytest.approx(height / climb + settle)
    # with an acceleration, eq. 4.2 from rest to rest: 2·sqrt(S/a) when the top speed is not reached
    m = _load(rovers={"climb_rate": 2.0, "accel": 1.0})
    assert m.rovers.takeoff_time == pytest.approx(2.0 * math.sqrt(height / 1.0) + settle)
    m = _load(rovers={"climb_rate": 0.5, "accel": 4.0})  # top speed reached: S/v + v/a
    assert m.rovers.takeoff_time == pytest.approx(height / 0.5 + 0.5 / 4.0 + settle)


def _land_time(cell: str) -> None:
    height, settle = _numbers(r"^\(([\d.]+) m − `carrier\.deck_height`\) / `land_speed` \+ ([\d.]+) s", cell)
    for land in (0.5, 2.0):
        for deck in (0.0, 0.5):
            m = _load(rovers={"land_speed": land}, carrier={"deck_height": deck})
            assert m.rovers.land_time == pytest.approx((height - deck) / land + settle)


def _climb_rate(cell: str) -> None:
    assert cell == "`max_speed`"
    assert _load(rovers={"max_speed": 3.0}).rovers.climb_rate == 3.0


def _land_speed(cell: str) -> None:
    assert cell == "`climb_rate`"
    assert _load(rovers={"climb_rate": 1.5}).rovers.land_speed == 1.5


def _endurance_range(cell: str) -> None:
    (factor,) = _numbers(r"the larger of ([\d.]+) × `deploy_range`", cell)
    (seconds,) = _numbers(r"and a ([\d.]+) s battery at `max_speed`", cell)
    assert "rho · initial with `energy`" in cell
    for speed in (0.01, 2.0):  # the battery, then the deploy range is the larger
        m = _load(rovers={"max_speed": speed})
        assert m.rovers.endurance_range == pytest.approx(max(factor * 25.0, seconds * speed))
    m = _load(rovers={"deploy_range": None, "energy": {"initial": 100.0, "task": 10.0, "rho": 2.0}})
    assert m.rovers.endurance_range == pytest.approx(200.0)


def _firmware_speeds(cell: str) -> None:
    assert cell.startswith("`set` on real links, `keep` on `sim`")
    assert _load().rovers.firmware_speeds == "keep" and _load().carrier.firmware_speeds == "keep"
    real = _load(carrier={"connection": "udpin://0.0.0.0:14550"})
    assert real.rovers.firmware_speeds == "set" and real.carrier.firmware_speeds == "set"


def _sysid_start(cell: str) -> None:
    (offset,) = _numbers(r"carrier sysid \+ (\d+)", cell)
    assert [u.sysid for u in _load().rovers.units] == [3 + offset, 4 + offset]


def _fleet_count(cell: str) -> None:
    assert cell.startswith("the number of tasks")
    assert [u.id for u in _load().rovers.units] == ["r1", "r2"]


def _fleet(cell: str) -> None:
    assert cell.startswith("`count` = number of tasks, ")
    _sysid_start(cell)
    _fleet_count("the number of tasks")


def _unit_connection(cell: str) -> None:
    assert cell.startswith("the carrier's link")
    m = _load(carrier={"connection": "udpin://0.0.0.0:14550"},
              rovers={"units": [{"id": "a", "sysid": 11}, {"id": "b", "sysid": 12}]})
    assert set(fleet_urls(m).values()) == {"udpin://0.0.0.0:14550"}


def _ground_z(cell: str) -> None:
    assert cell == "`z = 0`"
    assert _load().tasks[0].position[2] == 0.0


def _origin_alt(cell: str) -> None:
    assert cell.startswith("`origin.alt`")
    assert _load().tasks[1].position[2] == pytest.approx(0.0)  # lat/lon without alt: on the ground


def _roadmap(name: str) -> Callable[[str], None]:
    def probe(cell: str) -> None:
        documented = float(cell.strip("`"))
        assert getattr(_load().environment()["roadmap"], name) == documented == getattr(RoadmapParams(), name)

    return probe


def _roadmap_section(cell: str) -> None:
    assert cell == "the planner's defaults"
    assert _load().environment()["roadmap"] == RoadmapParams()


def _topic_prefix(cell: str) -> None:
    assert cell == "`fleetctl/<name>`"
    m = _load(mqtt={"url": "mqtt://127.0.0.1:1883"})
    assert m.mqtt is not None and m.mqtt.topic_prefix == "fleetctl/defaults"


def _name(cell: str) -> None:
    assert cell == "the file name without `.yaml`"
    data = dict(BASE)
    del data["name"]
    assert parse_mission_text(yaml.safe_dump(data), "any", path=Path("dir/hill.yaml")).name == "hill"


def _sim(cell: str) -> None:
    documented = yaml.safe_load(cell.strip("`"))
    assert documented == schema.TOP["sim"][1]
    m = _load()
    assert (m.sim.speedup, m.sim.faults) == (documented["speedup"], tuple(documented["faults"]))


def _obstacles(cell: str) -> None:
    assert cell == "`[]`" and _load().obstacles == ()


def _task_duration(cell: str) -> None:
    assert cell == "`dwell`"
    m = _load(dwell=42.0, operation=True, rovers={"fleet": {"count": 1}})
    assert m.task_work("t1").duration == 42.0


def _task_work(cell: str) -> None:
    assert cell == "`rovers.work`"
    for mode in ("hover", "ground"):
        m = _load(operation=True, rovers={"work": mode, "fleet": {"count": 1}})
        assert m.task_work("t1").ground == (mode == "ground")


def _faults(cell: str) -> None:
    assert cell == "`[]`" and _load().sim.faults == ()


PROBES: dict[str, Callable[[str], None]] = {
    "rovers.takeoff_time": _takeoff_time,
    "rovers.land_time": _land_time,
    "rovers.climb_rate": _climb_rate,
    "rovers.land_speed": _land_speed,
    "rovers.endurance_range": _endurance_range,
    "rovers.firmware_speeds": _firmware_speeds,
    "carrier.firmware_speeds": _firmware_speeds,
    "rovers.fleet": _fleet,
    "rovers.fleet.count": _fleet_count,
    "rovers.fleet.sysid_start": _sysid_start,
    "rovers.units.connection": _unit_connection,
    "tasks.position": _ground_z,
    "collection.rovers.position": _ground_z,
    "tasks.alt": _origin_alt,
    "collection.rovers.alt": _origin_alt,
    **{f"planner.roadmap.{k}": _roadmap(k) for k in ("xi1", "xi2", "xi3", "xi4", "phi")},
    "planner.roadmap": _roadmap_section,
    "mqtt.topic_prefix": _topic_prefix,
    "name": _name,
    "sim": _sim,
    "obstacles": _obstacles,
    "sim.faults": _faults,
    "tasks.duration": _task_duration,
    "tasks.work": _task_work,
}


def _doc_rows() -> dict[str, list[str]]:
    """Key path -> the cells of its first row in docs/mission-file.md (``obstacles`` is the section's
    row, not the ``obstacles[]`` polygon row after it)."""
    rows: dict[str, list[str]] = {}
    for line in (DOCS / "mission-file.md").read_text(encoding="utf-8").splitlines():
        if m := re.match(r"^\| `([A-Za-z0-9_.\[\]]+)` \|", line):
            rows.setdefault(m[1].replace("[]", ""), [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]])
    return rows


def _worked_out_defaults() -> dict[str, str]:
    """Key -> documented default of every row whose loader default is not shown literally (by any
    loader table whose keys are all documented under the row's section)."""
    rows = _doc_rows()
    shown: dict[str, bool] = {}
    for _, spec in _loader_specs():
        for key in rows:
            section, _, leaf = key.rpartition(".")
            if leaf in spec and all((f"{section}.{k}" if section else k) in rows for k in spec):
                shown[key] = shown.get(key, False) or _default_shown(spec[leaf][1]) is not None
    return {key: rows[key][3] for key, literal in shown.items() if not literal}


def test_every_worked_out_default_is_absent_or_probed() -> None:
    unchecked = {k: cell for k, cell in _worked_out_defaults().items()
                 if k not in PROBES and not ABSENT.match(cell)}
    assert not unchecked, f"defaults in docs/mission-file.md no test checks (add a probe): {unchecked}"


def test_every_probe_has_its_row() -> None:
    assert set(PROBES) <= set(_doc_rows())


@pytest.mark.parametrize("key", sorted(PROBES))
def test_the_documented_default_is_the_loaders(key: str) -> None:
    PROBES[key](_doc_rows()[key][3])


def _module_constants() -> dict[str, list[float]]:
    """NAME -> the values of every module-level ``NAME = number`` in fleetctl/ and planners/."""
    root = Path(__file__).resolve().parents[2]
    out: dict[str, list[float]] = {}
    for path in sorted([*(root / "fleetctl").rglob("*.py"), *(root / "planners").rglob("*.py")]):
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if not (isinstance(node, ast.Assign) and len(node.targets) == 1):
                continue
            target, value = node.targets[0], node.value
            number = isinstance(value, ast.Constant) and isinstance(value.value, int | float)
            if isinstance(target, ast.Name) and number:
                assert isinstance(value, ast.Constant)
                out.setdefault(target.id, []).append(float(value.value))
    return out


def test_constants_quoted_in_the_docs_are_the_codes() -> None:
    """``TAKEOFF_SETTLE = 0.1 s`` in docs/time-model.md (and any ``NAME = number`` in a doc) is the
    value of that constant in the code."""
    constants = _module_constants()
    assignment = re.compile(r"\b([A-Z][A-Z0-9_]{3,}) = (\d+(?:\.\d+)?)\b")
    quoted = [(doc.name, m[1], float(m[2])) for doc in sorted(DOCS.glob("*.md"))
              for m in assignment.finditer(doc.read_text(encoding="utf-8"))]
    assert any(name == "TAKEOFF_SETTLE" for _, name, _ in quoted)
    wrong = [(doc, name, value, constants.get(name)) for doc, name, value in quoted
             if value not in constants.get(name, [])]
    assert not wrong, f"(doc, constant, quoted, the code's): {wrong}"


def test_the_documented_release_height_is_the_launchers() -> None:
    """docs/time-model.md: the carrier leaves a deployment stop once its rovers are 0.95 m up (the
    top of the take-off the time model's takeoff_time climbs, less 5 cm) or their take-off item is
    reached."""
    from fleetctl.mission.flight import TAKEOFF_HEIGHT
    from fleetctl.run.launch import CLEAR_HEIGHT

    text = " ".join((DOCS / "time-model.md").read_text(encoding="utf-8").split())
    assert CLEAR_HEIGHT == pytest.approx(TAKEOFF_HEIGHT - 0.05)
    assert f"its take-off item reached, or {CLEAR_HEIGHT:g} m above it" in text
    assert f"`CLEAR_HEIGHT = TAKEOFF_HEIGHT - {TAKEOFF_HEIGHT - CLEAR_HEIGHT:g}` m" in text
