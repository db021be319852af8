"""docs/records.md lists every kind of journal record the code writes, and only those.

The kinds written are the values of :class:`fleetctl.run.kinds.Ev` and the kinds the code passes
as string literals to the journal's writers (``write``, ``commit``, ``record``, ``event``, the
teams' ``_event``, the preflight's ``notes``), found by reading the source, so a new kind written
anywhere fails this test until it is documented."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from fleetctl.run.kinds import Ev

ROOT = Path(__file__).resolve().parents[2]
WRITERS = {"write", "commit", "record", "event", "_event"}
KIND = re.compile(r"[a-z][a-z_]*")
# kinds built at run time from a prefix: the prefix -> every kind it makes (none today: the bus's
# connection states are Ev members, fleetctl/bus/config.py STATUS_EVENT)
BUILT: dict[str, set[str]] = {}


def _literal(node: ast.expr) -> str | None:
    if isinstance(node, ast.Constant) and isinstance(node.value, str) and KIND.fullmatch(node.value):
        return node.value
    return None


def _prefix(node: ast.expr) -> str | None:
    """``"bus_" + status`` or ``f"bus_{status}"`` -> ``"bus_"``."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        head = node.left
    elif isinstance(node, ast.JoinedStr) and node.values:
        head = node.values[0]
    else:
        return None
    if isinstance(head, ast.Constant) and isinstance(head.value, str):
        return head.value if re.fullmatch(r"[a-z_]+_", head.value) else None
    return None


def written_kinds() -> tuple[set[str], set[str]]:
    """(the kinds the code writes, the prefixes of kinds it builds) from the source of fleetctl/."""
    kinds = {e.value for e in Ev}
    prefixes: set[str] = set()
    for path in sorted((ROOT / "fleetctl").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and node.args:
                f = node.func
                name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
                first = node.args[0]
                if name in WRITERS:
                    if (k := _literal(first)) is not None:
                        kinds.add(k)
                    elif (p := _prefix(first)) is not None:
                        prefixes.add(p)
                elif name == "append" and isinstance(first, ast.Tuple) and len(first.elts) == 3:
                    if (k := _literal(first.elts[0])) is not None:  # (kind, text, vehicle) notes
                        kinds.add(k)
            elif (isinstance(node, ast.Assign) and len(node.targets) == 1
                  and isinstance(node.targets[0], ast.Name) and node.targets[0].id == "kind"):
                if (k := _literal(node.value)) is not None:  # kind = "bus_failed"; ...record(kind)
                    kinds.add(k)
    return kinds, prefixes


def documented_kinds() -> set[str]:
    """The kinds in the first column of the table of kinds in docs/records.md."""
    text = (ROOT / "docs" / "records.md").read_text(encoding="utf-8")
    table = text.split("\n| kind | data | when |", 1)[1].split("\n\n", 1)[0]
    kinds: set[str] = set()
    for line in table.splitlines():
        if line.startswith("| `"):
            kinds |= set(re.findall(r"`([a-z_]+)`", line.split("|")[1]))
    return kinds


def test_the_scan_finds_the_kinds_written_as_literals() -> None:
    kinds, prefixes = written_kinds()
    # every kind is written as an Ev member today (tests/test_journal_kinds.py keeps it so): the
    # scan's literals and prefixes are what a new call site would add before it is moved to Ev
    assert {"task_reached", "team_claim", "team_peer", "failsafe_set", "bus_telemetry_failed"} <= kinds
    assert kinds == {e.value for e in Ev}
    assert prefixes == set()


def test_every_built_kind_has_its_kinds_listed_here() -> None:
    _, prefixes = written_kinds()
    assert prefixes <= set(BUILT), f"kinds built from {sorted(prefixes - set(BUILT))}: list them in BUILT"


def test_records_md_lists_every_journal_kind() -> None:
    kinds, prefixes = written_kinds()
    for p in prefixes:
        kinds |= BUILT.get(p, set())
    documented = documented_kinds()
    assert not kinds - documented, f"docs/records.md does not list the kinds {sorted(kinds - documented)}"
    assert not documented - kinds, f"docs/records.md lists kinds no code writes: {sorted(documented - kinds)}"
