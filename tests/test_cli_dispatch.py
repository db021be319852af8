"""The command line's package (fleetctl.cli): the parser names a command, main imports the module
that runs it. Every command the parser offers has its function; ``--help`` and a usage error load
no command module, no mission code and no NumPy (a command loads what it needs when it runs)."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from fleetctl.cli import COMMAND_MODULES, build_parser, command_function

ROOT = Path(__file__).resolve().parents[1]


def _commands(parser: argparse.ArgumentParser) -> set[str]:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return set(sub.choices)


def test_every_command_of_the_parser_has_its_function() -> None:
    assert _commands(build_parser()) == set(COMMAND_MODULES)
    for command in COMMAND_MODULES:
        assert callable(command_function(command)), command


def _modules_after(argv: list[str]) -> tuple[int, set[str]]:
    code = ("import sys\nfrom fleetctl.cli import main\n"
            f"try:\n    rc = main({argv!r})\nexcept SystemExit as e:\n    rc = e.code\n"
            "print('\\nloaded', rc, ' '.join(sorted(sys.modules)))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT,
                         timeout=120).stdout.splitlines()[-1].split()
    assert out[0] == "loaded"
    return int(out[1]), set(out[2:])


def test_help_and_usage_errors_load_no_command_and_no_mission_code() -> None:
    for argv, rc in ((["--help"], 0), (["deploy", "--help"], 0), (["plan"], 2), (["nope"], 2)):
        code, loaded = _modules_after(argv)
        assert code == rc, argv
        heavy = {m for m in loaded if m.split(".")[0] in ("numpy", "asyncio", "rich", "pymavlink", "aiomqtt")}
        commands = {m for m in loaded if m in {f"fleetctl.cli.{mod}" for mod, _ in COMMAND_MODULES.values()}}
        assert not heavy and not commands and "fleetctl.mission" not in loaded, (argv, heavy, commands)


def test_a_command_loads_its_module_only() -> None:
    code, loaded = _modules_after(["plan", "--mission", str(ROOT / "missions" / "recon.yaml"), "--json",
                                   "--budget-ms", "0"])
    assert code == 0
    assert "fleetctl.cli.plan" in loaded
    assert not {"fleetctl.cli.fly", "fleetctl.cli.status", "fleetctl.cli.watch"} & loaded
    assert not {m for m in loaded if m.split(".")[0] in ("pymavlink", "aiomqtt", "matplotlib")}
