"""Records of a run under ``runs/<mission>-<timestamp>/``.

* ``journal.jsonl`` - one JSON object per line: ``{"t": unix, "elapsed": s, "kind": ..., ...}``
  (plan, each command and its ack, stop reached, rover launched, task reached, rover loaded,
  link lost/back, replans);
* ``traffic.tlog`` - every MAVLink message in and out (:class:`fleetctl.tlog.TlogWriter` on the
  links' tap), readable by pymavlink / ``mavlogdump.py``;
* ``plan.json`` (``plan-collect.json`` for the collection of ``run``) - the plan JSON contract;
* ``summary.json`` - the run summary (``schema fleetctl.summary/1``).

Lines are buffered and written by a worker thread in the background, so the event loop never
waits on the disk; :meth:`Journal.aclose` writes the rest.
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from typing import Any

from fleetctl.background_file import BackgroundFile
from fleetctl.mavlink.tlog import TlogWriter
from fleetctl.run.state import Event

log = logging.getLogger(__name__)

SUMMARY_SCHEMA = "fleetctl.summary/1"


def run_dir_for(mission_name: str, base: str | Path = "runs") -> Path:
    """A new, unique ``<base>/<mission>-<timestamp>`` directory (created)."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    base = Path(base)
    for n in range(1000):
        d = base / (f"{mission_name}-{stamp}" + (f"-{n}" if n else ""))
        try:
            d.mkdir(parents=True, exist_ok=False)
            return d
        except FileExistsError:
            continue
    raise FileExistsError(f"cannot create a run directory under {base}")


def json_safe(value: Any) -> Any:
    """JSON-safe: NaN/inf -> None, tuples -> lists, unknown objects -> str."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple | set | frozenset):
        return [json_safe(v) for v in value]
    if value is None or isinstance(value, bool | int | str):
        return value
    return str(value)


class Journal(BackgroundFile[str]):
    """The records of one run. ``write(kind, **data)`` is cheap (no I/O in the caller)."""

    def __init__(self, run_dir: str | Path, flush_interval: float = 0.5) -> None:
        self.dir = Path(run_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        super().__init__(self.dir / "journal.jsonl", binary=False, flush_interval=flush_interval)
        self.tlog_path = self.dir / "traffic.tlog"
        self.summary_path = self.dir / "summary.json"
        self.tlog = TlogWriter(self.tlog_path, flush_interval=flush_interval)
        self.started = time.monotonic()
        self._observers: list[Callable[[dict[str, Any]], None]] = []

    def add_observer(self, observer: Callable[[dict[str, Any]], None]) -> Callable[[], None]:
        """Call ``observer(record)`` with every record as it is written (e.g. the MQTT bus); it must
        not block and must not change the record. Returns a function that removes it."""
        self._observers.append(observer)
        return lambda: self._observers.remove(observer) if observer in self._observers else None

    # -- writing -----------------------------------------------------------------------------
    def write(self, kind: str, **data: Any) -> None:
        if self._closed:
            return
        rec = {"t": round(time.time(), 3), "elapsed": round(time.monotonic() - self.started, 3), "kind": kind}
        rec.update(json_safe(data))
        self.queue(json.dumps(rec, separators=(",", ":")))
        for observer in list(self._observers):
            try:
                observer(rec)
            except Exception:  # noqa: BLE001 - an observer must not stop the mission
                log.exception("journal observer failed")

    def on_event(self, ev: Event) -> None:
        """A :class:`fleetctl.fleet.FleetState` listener: journal every event."""
        self.write(ev.kind, vehicle=ev.vehicle, text=ev.text, **ev.data)

    def tap(self) -> Callable[[str, float, bytes], None]:
        """The link tap writing the ``.tlog``."""
        return self.tlog

    def write_json(self, name: str, data: Any) -> Path:
        """Write a whole JSON file into the run directory (small; plan and summary)."""
        path = self.dir / name
        path.write_text(json.dumps(json_safe(data), indent=1) + "\n", encoding="utf-8")
        return path

    # -- background ----------------------------------------------------------------------------
    def start(self) -> None:
        """Flush journal and tlog in the background (needs a running loop)."""
        self.tlog.start()
        super().start()

    async def aclose(self) -> None:
        await self.tlog.aclose()
        await super().aclose()


def write_summary(summary: dict[str, Any], *paths: str | Path | None) -> None:
    """Write the run summary JSON to every given path (parents created)."""
    text = json.dumps(json_safe(summary), indent=1) + "\n"
    for p in paths:
        if p is None:
            continue
        p = Path(p)
        if p.parent and not p.parent.exists():
            p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text, encoding="utf-8")


__all__ = ["SUMMARY_SCHEMA", "Journal", "run_dir_for", "write_summary"]
