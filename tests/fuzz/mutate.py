"""A seeded mutation generator for mission files, and the in-process runner of one case.

``mutations(seed, n)`` yields ``Case`` s: a mutation kind and the mutated file text, made from the
shipped missions (``missions/``). Kinds (:data:`KINDS`): type flips, deletions, extreme numbers,
huge lists, unicode, duplicate keys, YAML aliases (bombs, recursive, misplaced), garbage bytes,
deep nesting, YAML tags, many obstacles, roadmap parameters. Same seed, same cases.

``run_case(text, path)`` writes the file and runs ``fleetctl plan --json`` in-process
(``fleetctl.cli.main``) with captured output, and classifies the result:

* ``ok`` - exit 0 and the output is valid, finite JSON;
* ``error`` - exit 2 and one ``fleetctl: error: ...`` message;
* ``traceback`` - any exception escaped ``main`` (the ``detail`` holds it);
* ``bad_json`` - exit 0 but the output is not JSON or holds NaN/Infinity;
* ``bad_exit`` - any other exit code or an error without a message.

Used by ``tests/fuzz/test_fuzz_missions.py`` (a few hundred cases) and ``bench/fuzz_missions.py``
(thousands, in worker processes with a timeout and a memory cap).
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import random
import traceback
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[2]
MISSIONS = sorted([*ROOT.glob("missions/*.yaml"), *ROOT.glob("missions/paper/*.yaml")])

KINDS = ("type_flip", "delete", "extreme_number", "huge_list", "unicode", "duplicate_key", "alias",
         "garbage", "deep_nesting", "tag", "obstacles", "roadmap")

EXTREME_NUMBERS = ("0", "-0.0", "-1", "1e308", "1.79e308", "-1e308", "1.79e+308", "1.0e+308", "-1.0e+308",
                   "1.0e+400", "1.0e-400", "2.5e+15", "1.0e+6", "4.0e+4", "1.0e+3", "1e-308", "5e-324",
                   ".inf", "-.inf",
                   ".nan", "9" * 400, "-" + "9" * 30, str(2**63), str(2**64 + 1), "1e20", "256", "1e6",
                   "0x7fffffff", "0o777", "1_000_000", "123456789012345678901234567890.5", "1e400", "65535",
                   "255", "-90.0000001", "180.5", "0.0000001", "12:30:00", "1.5e3")
UNICODE = ("t\u00e9che", "\u0442\u0430\u0441\u043a", "\U0001f681\U0001f681", "\u202etxet", "a\u0000b",
           "\ufeffid", "\u00a0", "", " ", "x" * 5000, "\u4efb\u52a1", "\\N", "'quoted'", "\"dq\"", "null",
           "~", "yes", "1e3")
TAGS = ("!!python/object/apply:os.system ['true']", "!!python/name:os.system", "!!binary aGVsbG8=",
        "!!timestamp 2001-12-14", "!!set {a, b}", "!!float abc", "!!int 12x", "!custom 5", "!!omap [a: 1]",
        "!!str 5", "!!float 1e999", "2020-13-45", "!!null x", "!!bool maybe", "!!pairs [a: 1]",
        "!<tag:yaml.org,2002:int> 99999999999999999999999999999999999999999999999999")


@dataclass(frozen=True)
class Case:
    index: int
    kind: str
    base: str  # the mission file it came from
    text: str
    collect: bool = False  # plan the collection (--collect): the base has a collection section


@dataclass
class Result:
    outcome: str  # ok | error | traceback | bad_json | bad_exit
    exit_code: int | None
    detail: str
    stdout: str = ""


# --------------------------------------------------------------------------- data-level helpers


def _paths(data: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [path]
    if isinstance(data, dict):
        for k, v in data.items():
            out += _paths(v, path + (k,))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            out += _paths(v, path + (i,))
    return out


def _get(data: Any, path: tuple[Any, ...]) -> Any:
    for p in path:
        data = data[p]
    return data


def _set(data: Any, path: tuple[Any, ...], value: Any) -> Any:
    if not path:
        return value
    _get(data, path[:-1])[path[-1]] = value
    return data


def _random_value(rng: random.Random) -> Any:
    return rng.choice([None, True, False, 0, -1, 3.5, "x", "", [], {}, [1, 2, 3], {"a": 1}, [[1, 2]],
                       "1e3", [None], {"id": None}, 10**30])


def _dump(data: Any) -> str:
    return yaml.safe_dump(data, sort_keys=False, allow_unicode=True)


def _number_lines(lines: list[str]) -> list[int]:
    import re

    rx = re.compile(r"(?<![\w.])-?\d+(\.\d+)?(e[+-]?\d+)?(?![\w.])")
    return [i for i, line in enumerate(lines) if rx.search(line.split("#")[0])]


# --------------------------------------------------------------------------- mutations


def _type_flip(rng: random.Random, data: Any, text: str) -> str:
    paths = _paths(data)[1:]
    for _ in range(rng.randint(1, 3)):
        p = rng.choice(paths)
        with contextlib.suppress(KeyError, IndexError, TypeError):
            old = _get(data, p)
            new = _random_value(rng)
            while type(new) is type(old):
                new = _random_value(rng)
            data = _set(data, p, new)
            paths = _paths(data)[1:]
    return _dump(data)


def _delete(rng: random.Random, data: Any, text: str) -> str:
    for _ in range(rng.randint(1, 3)):
        paths = _paths(data)[1:]
        if not paths:
            break
        p = rng.choice(paths)
        with contextlib.suppress(KeyError, IndexError, TypeError):
            parent = _get(data, p[:-1])
            del parent[p[-1]]
    return _dump(data)


def _extreme_number(rng: random.Random, data: Any, text: str) -> str:
    import re

    lines = text.splitlines()
    idx = _number_lines(lines)
    rx = re.compile(r"(?<![\w.])-?\d+(\.\d+)?(e[+-]?\d+)?(?![\w.])")
    for _ in range(rng.randint(1, 3)):
        if not idx:
            break
        i = rng.choice(idx)
        code, sep, comment = lines[i].partition("#")
        matches = list(rx.finditer(code))
        if not matches:
            continue
        m = rng.choice(matches)
        code = code[:m.start()] + rng.choice(EXTREME_NUMBERS) + code[m.end():]
        lines[i] = code + sep + comment
    return "\n".join(lines) + "\n"


def _huge_list(rng: random.Random, data: Any, text: str) -> str:
    lists = [p for p in _paths(data) if isinstance(_get(data, p), list) and _get(data, p)]
    if not lists:
        return text
    p = rng.choice(lists)
    lst = _get(data, p)
    n = rng.choice([255, 300, 1000, 10_000, 100_000])
    if p == ("tasks",) and rng.random() < 0.5:  # distinct tasks and a fleet for them
        n = rng.choice([30, 100, 254, 255])
        lst[:] = [{"id": f"t{i}", "position": [rng.uniform(0, 90), rng.uniform(0, 90), 0]} for i in range(n)]
        rovers = data.get("rovers") if isinstance(data.get("rovers"), dict) else None
        if rovers is not None:
            rovers.pop("units", None)
            rovers["fleet"] = {"count": n, "sysid_start": 2}
        return _dump(data)
    lst[:] = [copy.deepcopy(lst[i % len(lst)]) for i in range(n)]
    return _dump(data)


def _unicode(rng: random.Random, data: Any, text: str) -> str:
    strings = [p for p in _paths(data) if isinstance(_get(data, p), str)]
    keys = [p for p in _paths(data) if p and isinstance(p[-1], str)]
    for _ in range(rng.randint(1, 3)):
        u = rng.choice(UNICODE)
        if strings and rng.random() < 0.6:
            data = _set(data, rng.choice(strings), u)
        elif keys:
            p = rng.choice(keys)
            with contextlib.suppress(KeyError, TypeError):
                parent = _get(data, p[:-1])
                parent[u] = parent.pop(p[-1])
            keys = [p for p in _paths(data) if p and isinstance(p[-1], str)]
        strings = [p for p in _paths(data) if isinstance(_get(data, p), str)]
    out = _dump(data)
    if rng.random() < 0.2:  # invalid UTF-8 or a raw control character
        out = out.replace("id:", rng.choice(["id\udcff:", "id\x07:", "i\u0085d:"]), 1)
    return out


def _duplicate_key(rng: random.Random, data: Any, text: str) -> str:
    lines = text.splitlines()
    keyed = [i for i, line in enumerate(lines)
             if ":" in line.split("#")[0] and not line.lstrip().startswith("-")]
    if not keyed:
        return text
    i = rng.choice(keyed)
    lines.insert(i + rng.randint(0, 1), lines[i])
    return "\n".join(lines) + "\n"


def _alias(rng: random.Random, data: Any, text: str) -> str:
    choice = rng.randrange(6)
    if choice == 0:  # billion laughs, appended as an extra key
        depth, width = rng.choice([(6, 6), (8, 8), (9, 10)])
        bomb = ["zz0: &a0 [lol, lol]"]
        for k in range(1, depth + 1):
            bomb.append(f"zz{k}: &a{k} [{', '.join(f'*a{k - 1}' for _ in range(width))}]")
        return text + "\n" + "\n".join(bomb) + "\n"
    if choice == 1:  # recursive alias
        return text + "\nzz: &r [1, *r]\n"
    if choice == 2:  # recursive mapping alias
        return text + "\nzz: &m {a: 1, b: *m}\n"
    if choice == 3:  # a bomb inside the tasks list
        return text.replace("tasks:", "tasks: &tt", 1) + "\nextra: [*tt, *tt, *tt]\n"
    if choice == 4:  # an undefined alias
        return text.replace("max_speed:", "max_speed: *nope #", 1)
    # a valid anchor reused in place of a number
    return text.replace("max_speed:", "max_speed: &sp", 1).replace("deploy_range:", "deploy_range: *sp #", 1)


def _garbage(rng: random.Random, data: Any, text: str) -> str:
    b = bytearray(text.encode("utf-8"))
    choice = rng.randrange(5)
    if choice == 0:
        del b[rng.randrange(len(b)):]  # truncated
    elif choice == 1:
        for _ in range(rng.randint(1, 20)):
            b[rng.randrange(len(b))] = rng.randrange(256)
    elif choice == 2:
        pos = rng.randrange(len(b))
        b[pos:pos] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 200)))
    elif choice == 3:
        b = bytearray(rng.choice([b"", b"\x00" * 100, b"---\n...\n", b"- - -", b"{", b"key: [", b":::",
                                  b"%YAML 9.9\n---\na: 1", b"--- 1\n--- 2\n", b"\t\ttab: 1"]))
    else:
        b = bytearray(rng.choice([b"a" * 2_000_000, b"x: " + b"y" * 1_500_000]))  # over the size cap
    return b.decode("utf-8", "surrogateescape")


def _deep_nesting(rng: random.Random, data: Any, text: str) -> str:
    n = rng.choice([40, 600, 5000, 20_000, 100_000])
    if rng.random() < 0.5:
        value = "[" * n + "]" * n
    else:
        value = "{a: " * n + "1" + "}" * n
    key = rng.choice(["max_speed", "tasks", "zz", "carrier"])
    if key == "zz" or key + ":" not in text:
        return text + f"\nzz: {value}\n"
    return text.replace(f"{key}:", f"{key}: {value} #", 1)


def _tag(rng: random.Random, data: Any, text: str) -> str:
    tag = rng.choice(TAGS)
    key = rng.choice(["max_speed:", "deploy_range:", "id:", "position:", "name:", "unload_time:"])
    if key not in text:
        return text + f"\nzz: {tag}\n"
    return text.replace(key, f"{key} {tag} #", 1)


def _obstacles(rng: random.Random, data: Any, text: str) -> str:
    if not isinstance(data, dict):
        return text
    n = rng.choice([10, 100, 501, 1000, 10_000])
    obs = []
    for _ in range(n):
        x, y = rng.uniform(-10_000, 10_000), rng.uniform(-10_000, 10_000)
        s = rng.uniform(0.01, 2.0)
        obs.append([[x, y], [x + s, y], [x + s, y + s], [x, y + s]])
    if rng.random() < 0.3:  # one polygon with many vertices
        import math

        k = rng.choice([100, 300, 5000])
        obs = [[[5000 + math.cos(2 * math.pi * i / k), 5000 + math.sin(2 * math.pi * i / k)]
                for i in range(k)]]
    data["obstacles"] = obs
    data.setdefault("bounds", [[-10_001, -10_001], [10_001, 10_001]])
    return _dump(data)


def _roadmap(rng: random.Random, data: Any, text: str) -> str:
    if not isinstance(data, dict):
        return text
    planner = data.get("planner") if isinstance(data.get("planner"), dict) else {}
    key = rng.choice(["xi1", "xi2", "xi3", "xi4", "phi"])
    planner["roadmap"] = {key: rng.choice([0, 1e-9, 0.5, 10, 256, 1000, 1e6, 1e308, 0.999, 1.0])}
    if rng.random() < 0.5:
        planner["deploy"] = planner["collect"] = "lee-graph"
    if rng.random() < 0.3:
        data["bounds"] = rng.choice([[[0, 0], [1e5, 1e5]], [[-1e5, -1e5], [1e5, 1e5]], [[0, 0], [1, 1]]])
    data["planner"] = planner
    if rng.random() < 0.3 and isinstance(data.get("rovers"), dict):
        data["rovers"]["deploy_range"] = rng.choice([1000, 1e5, 1e6])
        data["rovers"].pop("energy", None)
        data["rovers"].pop("endurance_range", None)
    return _dump(data)


_MUTATORS = {
    "type_flip": _type_flip, "delete": _delete, "extreme_number": _extreme_number, "huge_list": _huge_list,
    "unicode": _unicode, "duplicate_key": _duplicate_key, "alias": _alias, "garbage": _garbage,
    "deep_nesting": _deep_nesting, "tag": _tag, "obstacles": _obstacles, "roadmap": _roadmap,
}


def mutate(rng: random.Random, kind: str, text: str) -> str:
    data = yaml.safe_load(text)
    return _MUTATORS[kind](rng, data, text)


def mutations(seed: int, n: int, kinds: tuple[str, ...] = KINDS) -> Iterator[Case]:
    """``n`` cases, round-robin over ``kinds``; deterministic for ``seed``."""
    texts = {p: p.read_text(encoding="utf-8") for p in MISSIONS}
    bases = list(texts)
    for i in range(n):
        rng = random.Random(f"{seed}:{i}")
        kind = kinds[i % len(kinds)]
        base = rng.choice(bases)
        text = mutate(rng, kind, texts[base])
        collect = "\ncollection:" in texts[base] and ("tasks: []" in texts[base] or rng.random() < 0.5)
        yield Case(i, kind, base.name, text, collect)


# --------------------------------------------------------------------------- running one case


def _no_constant(name: str) -> Any:
    raise ValueError(f"non-finite number {name} in the JSON")


def check_output(rc: int, out: str, err: str) -> Result:
    if rc == 0:
        try:
            json.loads(out, parse_constant=_no_constant)
        except ValueError as exc:
            return Result("bad_json", rc, f"{exc}: {out[:300]}", out)
        return Result("ok", rc, "", out)
    if rc == 2 and "fleetctl: error: " in err and "Traceback" not in err:
        return Result("error", rc, err.strip().splitlines()[-1][:500])
    return Result("bad_exit", rc, err[-1000:])


def run_case(text: str, path: Path, collect: bool = False) -> Result:
    """Write ``text`` to ``path`` and run ``fleetctl plan --json`` on it in this process."""
    from fleetctl.cli import main

    path.write_bytes(text.encode("utf-8", "surrogateescape"))
    out, err = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc = main(["plan", "--json", "-m", str(path), *(["--collect"] if collect else [])])
    except SystemExit as exc:  # argparse
        return check_output(int(exc.code or 0), out.getvalue(), err.getvalue())
    except BaseException as exc:  # noqa: BLE001 - a crash is what the fuzzer looks for
        if isinstance(exc, KeyboardInterrupt):
            raise
        return Result("traceback", None, "".join(traceback.format_exception(exc))[-3000:])
    return check_output(rc, out.getvalue(), err.getvalue())


__all__ = ["KINDS", "Case", "Result", "check_output", "mutate", "mutations", "run_case"]
