"""The mission-file watcher of the supervisor survives every bad edit.

No flight: a Supervisor over a stub fleet watches a mission file; each bad edit (a recursive alias,
an alias bomb, a 400-digit number, a file over the size cap, a loader that raises something other
than MissionError) is rejected with a ``task_change_rejected`` event (journal and view) and the
next valid edit still arrives as a ``tasks`` event.
"""

from __future__ import annotations

import asyncio
import os
from pathlib import Path
from typing import Any

import pytest
import yaml

import fleetctl.run.supervisor as sup
from fleetctl.mission import load_mission
from fleetctl.mission.limits import MAX_FILE_BYTES
from fleetctl.run.state import FleetState
from fleetctl.run.supervisor import Supervisor
from tests.run.ctl_helpers import mission_dict


class StubFleet:
    rovers: dict[str, Any] = {}

    def add_listener(self, listener: Any) -> Any:
        return lambda: None


class Watch:
    def __init__(self, tmp_path: Path) -> None:
        self.d = mission_dict(rovers=3)
        self.path = tmp_path / "mission.yaml"
        self.text = yaml.safe_dump(self.d, sort_keys=False)
        self.path.write_text(self.text, encoding="utf-8")
        self.mission = load_mission(self.path)
        self.state = FleetState(self.mission, max_events=100)
        self.sup = Supervisor(self.mission, StubFleet(), self.state,  # type: ignore[arg-type]
                              tasks=lambda: {t.id: t for t in self.mission.tasks})
        self._ns = self.path.stat().st_mtime_ns

    def write(self, text: str | bytes) -> None:
        data = text.encode("utf-8", "surrogateescape") if isinstance(text, str) else text
        self.path.write_bytes(data)
        self._ns += 10_000_000  # a distinct mtime for every edit, whatever the clock granularity
        os.utime(self.path, ns=(self._ns, self._ns))

    def rejected(self) -> list[str]:
        return [e.text for e in self.state.events if e.kind == "task_change_rejected"]

    async def wait(self, pred: Any, what: str) -> None:
        for _ in range(400):
            if pred():
                return
            await asyncio.sleep(0.01)
        raise AssertionError(f"timed out waiting for {what}; rejected: {self.rejected()}")


@pytest.fixture(autouse=True)
def _fast_poll(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sup, "FILE_POLL_S", 0.02)


def valid_with_t3(w: Watch) -> str:
    d = dict(w.d)
    d["tasks"] = [*w.d["tasks"], {"id": "t3", "position": [5, 5, 2]}]
    return yaml.safe_dump(d, sort_keys=False)


BAD_EDITS = {
    "recursive alias": lambda w: w.text + "zz: &r [1, *r]\n",
    "alias bomb": lambda w: w.text + "z0: &a0 [l, l, l, l, l, l, l, l]\n" + "".join(
        f"z{k}: &a{k} [{', '.join(f'*a{k - 1}' for _ in range(8))}]\n" for k in range(1, 9)),
    "400 digits": lambda w: w.text.replace("max_speed: 5.0", "max_speed: " + "9" * 400),
    "deep nesting": lambda w: w.text + "zz: " + "[" * 20_000 + "]" * 20_000 + "\n",
    "garbage": lambda w: "\x00\udcff\udcfe" + w.text[:50],
    "too large": lambda w: w.text + "#" * (MAX_FILE_BYTES + 10) + "\n",
}


@pytest.mark.parametrize("kind", sorted(BAD_EDITS))
async def test_bad_edit_is_rejected_and_the_next_valid_edit_applies(tmp_path: Path, kind: str) -> None:
    w = Watch(tmp_path)
    w.sup.start()
    try:
        w.write(BAD_EDITS[kind](w))
        await w.wait(lambda: w.rejected(), "the rejection")
        assert "plan kept" in w.rejected()[0]
        assert w.sup.queue.empty()
        w.write(valid_with_t3(w))
        ev = await asyncio.wait_for(w.sup.queue.get(), 5)
        assert ev.kind == "tasks" and [t.id for t in ev.add] == ["t3"] and not ev.remove
        assert all(not t.done() for t in w.sup._bg)  # the watcher is still running
    finally:
        await w.sup.close()


async def test_unexpected_exception_does_not_stop_the_watcher(tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    w = Watch(tmp_path)
    calls = []

    def flaky(path: Path) -> Any:
        calls.append(path)
        if len(calls) == 1:
            raise RecursionError("maximum recursion depth exceeded")
        return load_mission(path)

    monkeypatch.setattr(sup, "load_mission", flaky)
    w.sup.start()
    try:
        w.write(w.text + "# edit 1\n")
        await w.wait(lambda: w.rejected(), "the rejection")
        assert "RecursionError" in w.rejected()[0]
        w.write(valid_with_t3(w))
        ev = await asyncio.wait_for(w.sup.queue.get(), 5)
        assert [t.id for t in ev.add] == ["t3"]
    finally:
        await w.sup.close()
