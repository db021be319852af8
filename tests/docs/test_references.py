"""What the docs and the code point at exists, inside the repository: every dotted name of a
module (``fleetctl.run.state.FleetState``, ``planners.core.timing``, ``sitl.world``) imports, every
repository path of a source or doc file is there, and nothing points at files outside the
repository (developer notes) or at issue numbers a user cannot look up."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("fleetctl", "planners", "sitl", "bench")
SOURCE_SUFFIXES = {".py", ".sh", ".js", ".html", ".css", ".toml"}
THIS = Path(__file__).resolve()


def _files() -> list[Path]:
    """Every source and doc file of the repository: the packages, bench/, scripts/, tests/, docs/,
    the example missions, the README and pyproject.toml (this test's own file excepted: it spells
    out what it looks for)."""
    out = [ROOT / "README.md", ROOT / "pyproject.toml", *sorted((ROOT / "docs").glob("*.md")),
           *sorted((ROOT / "missions").glob("*.yaml"))]
    for top in (*PACKAGES, "scripts", "tests"):
        out += sorted(p for p in (ROOT / top).rglob("*") if p.suffix in SOURCE_SUFFIXES | {".md"})
    return [p for p in out if p.resolve() != THIS and "__pycache__" not in p.parts]


def _hits(pattern: str, flags: int = 0) -> list[tuple[str, int, str]]:
    rx = re.compile(pattern, flags)
    return [(str(path.relative_to(ROOT)), n, m[0]) for path in _files()
            for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
            for m in rx.finditer(line)]


# ``fleetctl.x.y``, ``planners.x``... not part of a path, a file name or a format (``fleetctl.plan/1``)
DOTTED = r"(?<![\w./-])(?:fleetctl|planners|sitl|bench)(?:\.[A-Za-z_]\w*)+(?![\w/-])"
FILE_NAME = re.compile(r"\.(py|md|yaml|json|parm|tlog|plan|csv|kml|sh)$")


def _resolves(name: str) -> bool:
    """A module (file or package directory) and then attributes of it."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        base = ROOT.joinpath(*parts[:i])
        if base.with_suffix(".py").is_file() or base.is_dir():
            if i == len(parts):
                return True
            obj: object = importlib.import_module(".".join(parts[:i]))
            for attr in parts[i:]:
                if not hasattr(obj, attr):
                    return False
                obj = getattr(obj, attr)
            return True
    return False


def test_every_module_named_exists() -> None:
    names = [(f, n, name.rstrip(".")) for f, n, name in _hits(DOTTED) if not FILE_NAME.search(name)]
    assert len(names) > 100  # the scan sees the docstrings
    missing = [(f"{f}:{n}", name) for f, n, name in names if not _resolves(name)]
    assert not missing, f"names of modules or attributes that do not exist: {missing}"


def test_every_repository_path_named_exists() -> None:
    tops = "fleetctl|planners|sitl|bench|tests|scripts|docs"
    paths = _hits(rf"(?<![\w./-])(?:{tops})/[\w./-]*\.(?:py|md|sh|js)\b")
    assert len(paths) > 50
    missing = [(f"{f}:{n}", p) for f, n, p in paths if not (ROOT / p).exists()]
    assert not missing, f"paths of files that are not in the repository: {missing}"


def test_every_markdown_file_named_exists() -> None:
    names = {p.name for p in ROOT.rglob("*.md") if ".git" not in p.parts}
    missing = [(f"{f}:{n}", md) for f, n, md in _hits(r"(?<![\w./-])[\w-]+\.md\b") if md not in names]
    assert not missing, f"markdown files that are not in the repository: {missing}"


@pytest.mark.parametrize(("what", "pattern"), [
    ("developer notes outside the repository", r"DESIGN\.md|/work/|\bshared/"),
    ("issue numbers (say what the text means instead)", r"(?i)\bissues?\s*#?\d+|\bissue \d+'s\b"),
])
def test_no_pointer_outside_the_repository(what: str, pattern: str) -> None:
    hits = [f"{f}:{n}: {text}" for f, n, text in _hits(pattern)]
    assert not hits, f"{what}: {hits}"
