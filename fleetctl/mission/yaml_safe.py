"""Bounded YAML for mission files: safe tags only, alias expansion, nesting and size limited.

:func:`read_yaml` parses one document with a :class:`yaml.SafeLoader` whose composer counts,
while it composes, every node (an alias counts as the whole subtree it stands for), every alias
use and the nesting depth, and stops at the first limit of :mod:`fleetctl.mission.limits`. A
recursive alias (``a: &r [1, *r]``) is refused where it is used. Nothing ever walks the expanded
copies: the line map of key paths visits each node once, so a "billion laughs" file is refused
after a few hundred nodes of work, not after expanding it.

Every problem is a :class:`YamlError` carrying the 1-based line, which the loader turns into its
``file:line: ...; what to change`` message.
"""

from __future__ import annotations

import contextlib
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.parser import Parser
from yaml.reader import Reader
from yaml.resolver import Resolver
from yaml.scanner import Scanner

import fleetctl.mission.limits as limits

_CParser: Any
try:
    from yaml._yaml import CParser as _CParser
except ImportError:  # PyYAML without libyaml
    _CParser = None

KeyPath = tuple[str | int, ...]

_NUMBER_TAGS = ("tag:yaml.org,2002:int", "tag:yaml.org,2002:float")


class YamlError(Exception):
    """A mission file YAML problem at ``line`` (1-based; None when unknown)."""

    def __init__(self, line: int | None, message: str) -> None:
        super().__init__(message)
        self.line = line
        self.message = message


def _line(mark: Any) -> int | None:
    return mark.line + 1 if mark is not None else None


class BoundedLoader(Composer, SafeConstructor, Resolver):
    """Safe YAML, bounded: libyaml's scanner and parser (C, ~5x faster) when PyYAML has them,
    else PyYAML's; always the bounded Python composer below (depth, node and alias budgets, see
    the module doc) and the safe constructor."""

    def __init__(self, stream: str, *, max_depth: int = limits.MAX_YAML_DEPTH,
                 max_nodes: int = limits.MAX_YAML_NODES, max_aliases: int = limits.MAX_ALIASES) -> None:
        self._parser: Any = _CParser(stream) if _CParser is not None else _PyParser(stream)
        Composer.__init__(self)
        SafeConstructor.__init__(self)
        Resolver.__init__(self)
        self.max_depth, self.max_nodes, self.max_aliases = max_depth, max_nodes, max_aliases
        self._depth = 0
        self._nodes = 0  # expanded node count so far
        self._aliases = 0
        self._size: dict[int, int] = {}  # id(node) -> expanded size, once its composition is complete

    def _grow(self, n: int, mark: Any, what: str) -> None:
        self._nodes += n
        if self._nodes > self.max_nodes:
            raise YamlError(_line(mark), f"{what} makes the document larger than {self.max_nodes} values "
                                         "(lists, mappings and scalars, aliases counted expanded); a mission "
                                         "needs a few thousand: shorten the lists or use fewer aliases")

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            node = self.anchors.get(event.anchor)
            if node is not None:
                size = self._size.get(id(node))
                if size is None:
                    raise YamlError(_line(event.start_mark),
                                    f"alias *{event.anchor} refers to the node it is inside (a recursive "
                                    "alias); replace it with the values it should stand for")
                self._aliases += 1
                if self._aliases > self.max_aliases:
                    raise YamlError(_line(event.start_mark),
                                    f"more than {self.max_aliases} alias uses (*name) in one file; "
                                    "write the values out")
                self._grow(size, event.start_mark, f"alias *{event.anchor} ({size} values)")
            return super().compose_node(parent, index)
        start = self.peek_event()
        self._depth += 1
        if self._depth > self.max_depth:
            raise YamlError(_line(start.start_mark), _too_deep(self.max_depth))
        before = self._nodes
        self._grow(1, start.start_mark, "this value")
        try:
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        self._size[id(node)] = self._nodes - before
        return node

    def compose_scalar_node(self, anchor: Any) -> Any:
        node = super().compose_scalar_node(anchor)
        if node.tag in _NUMBER_TAGS and len(node.value) > limits.MAX_NUMBER_DIGITS:
            raise YamlError(_line(node.start_mark),
                            f"a number written with {len(node.value)} characters is not a physical value "
                            f"(at most {limits.MAX_NUMBER_DIGITS}); write a plain number like 12.5")
        return node

    def construct_object(self, node: Any, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep)
        except yaml.YAMLError:
            raise
        except YamlError:
            raise
        except Exception as exc:  # noqa: BLE001 - e.g. !!timestamp 2020-13-45, !!bool maybe
            raise YamlError(_line(node.start_mark), f"cannot read the value ({exc}); "
                                                    "write a plain number, string, list or mapping") from None

    def check_event(self, *choices: Any) -> bool:
        return bool(self._parser.check_event(*choices))

    def peek_event(self) -> Any:
        return self._parser.peek_event()

    def get_event(self) -> Any:
        return self._parser.get_event()

    def dispose(self) -> None:
        with contextlib.suppress(Exception):
            self._parser.dispose()


class _PyParser(Reader, Scanner, Parser):
    def __init__(self, stream: str) -> None:
        Reader.__init__(self, stream)
        Scanner.__init__(self)
        Parser.__init__(self)


def _too_deep(max_depth: int) -> str:
    return (f"lists/mappings nested more than {max_depth} levels deep; a mission file needs at most 5, "
            "flatten it")


def read_yaml(text: str) -> tuple[Any, dict[KeyPath, int]]:
    """Parse one YAML document (bounded, see the module doc): (data, key path -> 1-based line).

    Raises :class:`YamlError` for a limit, duplicate key or value that cannot be read, and
    :class:`yaml.YAMLError` for malformed YAML."""
    loader = BoundedLoader(text)
    try:
        try:
            node = loader.get_single_node()
            data = loader.construct_document(node) if node is not None else None
        except RecursionError:  # cannot happen below MAX_YAML_DEPTH; never a traceback all the same
            raise YamlError(None, "the YAML is nested too deeply; flatten it") from None
        except yaml.MarkedYAMLError as exc:
            # PyYAML ≥ 6.0.4 stops deep flow nesting in its scanner, before the composer's bound:
            # the same limit, said the same way
            if "maximum nesting depth" not in str(exc.problem or ""):
                raise
            mark = exc.context_mark or exc.problem_mark
            raise YamlError(None if mark is None else mark.line + 1, _too_deep(loader.max_depth)) from None
    finally:
        loader.dispose()
    lines: dict[KeyPath, int] = {}
    if node is not None:
        line_map(node, lines)
    return data, lines


def line_map(root: yaml.Node, lines: dict[KeyPath, int]) -> None:
    """Record the 1-based line of every key path; reject duplicate keys in a mapping.

    Each node is visited once: the contents of an alias (the same node again) keep the lines of
    their anchor, and key paths through an alias fall back to the alias's own line."""
    seen_nodes: set[int] = set()
    stack: list[tuple[yaml.Node, KeyPath]] = [(root, ())]
    while stack:
        node, path = stack.pop()
        if id(node) in seen_nodes:
            continue
        seen_nodes.add(id(node))
        if isinstance(node, yaml.MappingNode):
            seen: set[Any] = set()
            children: list[tuple[yaml.Node, KeyPath]] = []
            for key_node, value_node in node.value:
                key = key_node.value if isinstance(key_node, yaml.ScalarNode) else f"<{key_node.tag}>"
                lines.setdefault(path + (key,), key_node.start_mark.line + 1)
                if key in seen:
                    where = _fmt(path + (key,))
                    raise YamlError(key_node.start_mark.line + 1,
                                    f"{where}: duplicate key in the same mapping; keep only one")
                seen.add(key)
                children.append((value_node, path + (key,)))
            stack.extend(reversed(children))  # visited in document order: an anchor before its aliases
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                lines.setdefault(path + (i,), item.start_mark.line + 1)
            stack.extend((item, path + (i,)) for i, item in reversed(list(enumerate(node.value))))


def _fmt(path: KeyPath) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(top level)"


__all__ = ["BoundedLoader", "YamlError", "line_map", "read_yaml"]
