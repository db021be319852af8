"""The docs cannot fall behind the code: every mission-file key the loader knows is in
docs/mission-file.md, every command-line option is in docs/cli.md, links stay inside the repo."""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

import fleetctl.mission.schema as schema
import fleetctl.mission.values as values
from fleetctl.cli import build_parser
from fleetctl.mission import parse_mission
from fleetctl.mission.loader import parse_mission_text

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
WRITTEN_ELSEWHERE = {"time-model.md"}  # linked from docs/README.md, written with the time model change


def _doc_rows() -> dict[str, list[str]]:
    """Key path -> the cells of its row in docs/mission-file.md (``tasks[].id`` -> ``tasks.id``)."""
    rows = {}
    for line in (DOCS / "mission-file.md").read_text(encoding="utf-8").splitlines():
        m = re.match(r"^\| `([A-Za-z0-9_.\[\]]+)` \|", line)
        if m:
            rows[m[1].replace("[]", "")] = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
    return rows


def _doc_keys() -> set[str]:
    return set(_doc_rows())


def _default_shown(default: object) -> str | None:
    """How the doc's default column shows a loader default (None: not checked)."""
    if default is values.REQUIRED:
        return "required"
    if isinstance(default, bool):
        return f"`{str(default).lower()}`"
    if isinstance(default, int | float | str):
        return f"`{default}`"
    return None


def _loader_specs() -> Iterator[tuple[str, dict[str, tuple[object, object]]]]:
    """Every key → (parser, default) table of the schema (a new section is found without a list here)."""
    for name, value in vars(schema).items():
        if (isinstance(value, dict) and value and all(isinstance(k, str) for k in value)
                and all(isinstance(v, tuple) and len(v) == 2 and callable(v[0]) for v in value.values())):
            yield name, value


def test_the_loader_has_specs() -> None:
    names = {n for n, _ in _loader_specs()}
    assert {"TOP", "CARRIER", "ROVERS", "TASK", "MQTT", "GEOFENCE"} <= names, names


@pytest.mark.parametrize(("name", "spec"), list(_loader_specs()),
                         ids=lambda x: x if isinstance(x, str) else "")
def test_every_mission_key_is_documented(name: str, spec: dict[str, tuple[object, object]]) -> None:
    keys = _doc_keys()
    prefixes = {k.rsplit(".", 1)[0] if "." in k else "" for k in keys if k.rsplit(".", 1)[-1] in spec}
    full = [p for p in prefixes if all((f"{p}.{k}" if p else k) in keys for k in spec)]
    assert full, (f"{name}: keys {sorted(spec)} are not all documented under one section of "
                  "docs/mission-file.md (a row '| `section.key` | type | unit | default | limits |' each)")
    rows = _doc_rows()

    def defaults_agree(p: str) -> bool:  # the default column says what the loader does
        shown = {key: _default_shown(default) for key, (_parse, default) in spec.items()}
        return all(s is None or s in rows[f"{p}.{key}" if p else key][3] for key, s in shown.items())

    assert any(defaults_agree(p) for p in full), (
        f"{name}: the defaults in docs/mission-file.md (section {' or '.join(full)}) are not the loader's: "
        + ", ".join(f"{k}={_default_shown(d)}" for k, (_p, d) in spec.items()))


def test_every_documented_row_has_five_columns() -> None:
    for line in (DOCS / "mission-file.md").read_text(encoding="utf-8").splitlines():
        if re.match(r"^\| `[A-Za-z0-9_.\[\]]+` \|", line):
            cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
            assert len(cells) == 5, line


def test_the_mission_file_example_loads() -> None:
    text = (DOCS / "mission-file.md").read_text(encoding="utf-8")
    example = text.split("## A complete example", 1)[1].split("```yaml\n", 1)[1].split("```", 1)[0]
    m = parse_mission_text(example, "docs/mission-file.md")
    assert m.carrier.connection == "udpin://0.0.0.0:14550" and len(m.tasks) == 2
    assert parse_mission(dict(m.raw), "again").name == "recon"


def _commands(parser: argparse.ArgumentParser, name: str = "fleetctl") -> Iterator[tuple[str, list[str]]]:
    options: list[str] = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, p in action.choices.items():
                yield from _commands(p, f"{name} {sub}")
        elif action.option_strings and action.help != argparse.SUPPRESS and action.dest != "help":
            options += action.option_strings
    if options:
        yield name, options


def _sections() -> dict[str, str]:
    """``fleetctl deploy`` -> the text of its section in docs/cli.md (a heading may name several)."""
    text = (DOCS / "cli.md").read_text(encoding="utf-8")
    out: dict[str, str] = {}
    for part in re.split(r"^## ", text, flags=re.M)[1:]:
        heading, _, body = part.partition("\n")
        for cmd in re.findall(r"`(fleetctl[a-z \-]*)`", heading):
            out[cmd] = body
    return out


@pytest.mark.parametrize(("command", "options"), list(_commands(build_parser())), ids=lambda x: x
                         if isinstance(x, str) else "")
def test_every_option_is_documented(command: str, options: list[str]) -> None:
    sections = _sections()
    assert command in sections, f"docs/cli.md has no section '## `{command}`'"
    missing = [o for o in options if not re.search(rf"`{re.escape(o)}[ `]", sections[command])]
    assert not missing, f"docs/cli.md, section {command}: options {missing} are not documented"


def _markdown_files() -> list[Path]:
    return [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]


@pytest.mark.parametrize("path", _markdown_files(), ids=lambda p: p.name)
def test_links_stay_in_the_repo(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        assert not re.match(r"[a-z]+://", target), f"{path.name}: link outside the repo: {target}"
        file = target.split("#", 1)[0]
        if file and Path(file).name not in WRITTEN_ELSEWHERE:
            assert (path.parent / file).exists(), f"{path.name}: broken link {target}"


# no pointer to developer notes: tests/docs/test_references.py (docs and code)


def test_the_index_links_every_doc() -> None:
    index = (DOCS / "README.md").read_text(encoding="utf-8")
    for doc in [*DOCS.glob("*.md"), *(DOCS / name for name in WRITTEN_ELSEWHERE)]:
        if doc.name != "README.md":
            assert f"]({doc.name})" in index, doc.name
    assert "](docs/README.md)" in (ROOT / "README.md").read_text(encoding="utf-8")
