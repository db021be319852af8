"""Journal and event kinds are named only through their enums: :class:`fleetctl.kinds.Ev` for the
journal's records and operator events, :class:`fleetctl.mavlink.vehicle.VehicleEventKind` for a
vehicle's own events. An AST scan of fleetctl/ finds every call site that passes a kind as a string
literal (or builds one from a literal, ``"bus_" + status``), so a new one fails here."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from fleetctl.kinds import Ev
from fleetctl.mavlink.vehicle import VehicleEventKind
from fleetctl.run import kinds as run_kinds

ROOT = Path(__file__).resolve().parents[1]
# the methods whose first argument is a kind: the journal's writers, the state's and the teams'
# events, the run's tell/record callbacks, a vehicle's _emit
WRITERS = {"write", "commit", "record", "event", "_event", "_emit", "emit", "tell"}
KIND = re.compile(r"[a-z][a-z_]*")
PREFIX = re.compile(r"[a-z_]+_")  # the head of a kind built at run time


def _kind_text(node: ast.expr) -> str | None:
    """The kind a literal argument spells (``"bus"``, ``"bus_" + s``, ``f"bus_{s}"``), else None."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value if KIND.fullmatch(node.value) else None
    if isinstance(node, ast.BinOp):
        head: ast.expr | None = node.left
    elif isinstance(node, ast.JoinedStr) and node.values:
        head = node.values[0]
    else:
        return None
    if isinstance(head, ast.Constant) and isinstance(head.value, str) and PREFIX.fullmatch(head.value):
        return head.value + "…"
    return None


def _literal_kinds(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, kind) of every kind written as a literal in ``tree``."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
            args = list(node.args[:1]) if name in WRITERS else []
            args += [k.value for k in node.keywords if k.arg == "kind" and name in WRITERS]
            if name == "append" and node.args and isinstance(node.args[0], ast.Tuple) \
                    and len(node.args[0].elts) == 3:  # a (kind, text, vehicle) note
                args.append(node.args[0].elts[0])
            found += [(node.lineno, k) for a in args if (k := _kind_text(a)) is not None]
        elif isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "kind"
                                                  for t in node.targets):
            if (k := _kind_text(node.value)) is not None:  # kind = "bus_failed"; ...event(kind, ...)
                found.append((node.lineno, k))
    return found


def literal_kinds_in_fleetctl() -> list[str]:
    """``path:line: kind`` of every literal kind in fleetctl/."""
    return [f"{path.relative_to(ROOT)}:{line}: {kind!r}"
            for path in sorted((ROOT / "fleetctl").rglob("*.py"))
            for line, kind in _literal_kinds(ast.parse(path.read_text(encoding="utf-8")))]


def test_the_scan_finds_each_way_a_kind_is_written_as_a_literal() -> None:
    source = '''
journal.write("bus", url=u)
self.state.event("bus_" + status, text, None)
self.record(f"team_{what}", text=t)
self._emit("lost", timeout=1.0)
tell(kind="link_lost", text=t)
notes.append(("failsafe", text, rid))
kind = "bus_failed"
journal.write(Ev.BUS, url=u)
out.write(f"[{t}] {text}")
feature(kind="task")
'''
    found = [k for _, k in sorted(_literal_kinds(ast.parse(source)))]
    assert found == ["bus", "bus_…", "team_…", "lost", "link_lost", "failsafe", "bus_failed"]


def test_fleetctl_writes_no_kind_as_a_literal() -> None:
    found = literal_kinds_in_fleetctl()
    assert not found, "kinds written as literals (name them through Ev or VehicleEventKind):\n" + \
        "\n".join(found)


def test_ev_is_one_enum_reexported_by_the_run() -> None:
    assert run_kinds.Ev is Ev
    assert len({e.value for e in Ev}) == len(Ev)  # no alias: every member its own wire value


def test_vehicle_event_kinds_are_their_wire_values() -> None:
    assert {k.value for k in VehicleEventKind} == {
        "connected", "lost", "back", "armed", "disarmed", "mode", "landed_state", "geofence_breach",
        "mission_current", "item_reached", "statustext"}
