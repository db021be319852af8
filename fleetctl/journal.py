"""Records of a run under ``runs/<mission>-<timestamp>/``.

* ``journal.jsonl`` - one JSON object per line: ``{"t": unix, "elapsed": s, "kind": ..., ...}``
  (plan, each command and its ack, stop reached, rover launched, task reached, rover loaded,
  link lost/back, replans);
* ``traffic.tlog`` - every MAVLink message in and out (:class:`fleetctl.mavlink.tlog.TlogWriter` on the
  links' tap), readable by pymavlink / ``mavlogdump.py``; one per MAVLink link, ``traffic-<id>.tlog``
  for each link after the first (:meth:`Journal.link_tlog`);
* ``plan.json`` (``plan-collect.json`` for the collection of ``run``) - the plan JSON contract;
* ``summary.json`` - the run summary (``schema fleetctl.summary/1``).

* ``mission.yaml`` - a copy of the mission file the run was started with (``fleetctl resume``
  reads it).

Lines are buffered and written by a worker thread in the background, so the event loop never
waits on the disk; :meth:`Journal.aclose` writes the rest. The journal is *write-ahead*:
:meth:`Journal.commit` returns once the record (and everything before it) is written and
fsynced, and the run awaits it before it sends the command the record describes, so a journal
left by ``kill -9`` says what was commanded. :func:`read_journal` reads one back.
"""

from __future__ import annotations

import json
import logging
import math
import shutil
import time
from collections.abc import Callable, Iterator
from datetime import datetime
from pathlib import Path
from typing import Any

from fleetctl.background_file import BackgroundFile
from fleetctl.mavlink.tlog import TlogWriter
from fleetctl.run.state import Event

log = logging.getLogger(__name__)

SUMMARY_SCHEMA = "fleetctl.summary/1"
JOURNAL_NAME = "journal.jsonl"
MISSION_COPY = "mission.yaml"


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


Record = dict[str, Any]  # one journal line: {"t", "kind", ...} (docs/records.md)

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
        super().__init__(self.dir / JOURNAL_NAME, binary=False, flush_interval=flush_interval)
        self.tlog_path = self.dir / "traffic.tlog"
        self.summary_path = self.dir / "summary.json"
        self.tlog = TlogWriter(self.tlog_path, flush_interval=flush_interval)
        self._link_tlogs: dict[str, TlogWriter] = {}  # file name -> the log of a further link
        self._flushing = False
        self.started = time.monotonic()
        self._observers: list[Callable[[Record], None]] = []

    def add_observer(self, observer: Callable[[Record], None]) -> Callable[[], None]:
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

    async def commit(self, kind: str, **data: Any) -> None:
        """Write a record and return once it (and every record before it) is on disk: await this
        before sending the command it describes."""
        self.write(kind, **data)
        await self.sync()

    def save_mission(self, source: str | Path) -> Path:
        """Copy the mission file into the run directory (small; before anything flies)."""
        dest = self.dir / MISSION_COPY
        shutil.copyfile(source, dest)
        return dest

    def on_event(self, ev: Event) -> None:
        """A :class:`fleetctl.run.state.FleetState` listener: journal every event."""
        mission_t = None if ev.mission_time is None else round(ev.mission_time, 3)
        self.write(ev.kind, **{"vehicle": ev.vehicle, "text": ev.text, **ev.data, "T": mission_t})

    def tap(self) -> Callable[[str, float, bytes], None]:
        """The link tap writing the ``.tlog``."""
        return self.tlog

    def link_tlog(self, name: str) -> TlogWriter:
        """The ``.tlog`` called ``name`` in the run folder (one per link,
        :func:`fleetctl.mission.links.link_tlogs`): ``traffic.tlog`` is :attr:`tlog`; another is made
        on first use and flushed and closed with the journal."""
        if name == self.tlog_path.name:
            return self.tlog
        writer = self._link_tlogs.get(name)
        if writer is None:
            writer = self._link_tlogs[name] = TlogWriter(self.dir / name, flush_interval=self.flush_interval)
            if self._flushing:
                writer.start()
        return writer

    def write_json(self, name: str, data: Any) -> Path:
        """Write a whole JSON file into the run directory (small; plan and summary)."""
        path = self.dir / name
        path.write_text(json.dumps(json_safe(data), indent=1) + "\n", encoding="utf-8")
        return path

    # -- background ----------------------------------------------------------------------------
    def start(self) -> None:
        """Flush journal and tlogs in the background (needs a running loop)."""
        self._flushing = True
        for writer in (self.tlog, *self._link_tlogs.values()):
            writer.start()
        super().start()

    async def aclose(self) -> None:
        for writer in (self.tlog, *self._link_tlogs.values()):
            await writer.aclose()
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


class JournalError(Exception):
    """A journal that cannot be read back (missing, or a line in the middle that does not parse)."""


def read_journal(path: str | Path) -> list[Record]:
    """The records of a journal file. A last line cut short (a crash while the disk was being
    written) is dropped; a bad line anywhere else raises :class:`JournalError`."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as exc:
        raise JournalError(f"{path}: cannot read the journal: {exc.strerror or exc}") from None
    return list(_parse_lines(path, lines))


def _parse_lines(path: Path, lines: list[str]) -> Iterator[Record]:
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except ValueError:
            if n == len(lines):
                log.warning("%s:%d: last line cut short (crash while writing); ignored", path, n)
                return
            raise JournalError(f"{path}:{n}: not a journal record (invalid JSON)") from None
        if not isinstance(rec, dict) or not isinstance(rec.get("kind"), str):
            raise JournalError(f"{path}:{n}: not a journal record (no 'kind')")
        yield rec


__all__ = ["JOURNAL_NAME", "MISSION_COPY", "SUMMARY_SCHEMA", "Journal", "JournalError", "Record",
           "read_journal", "run_dir_for", "write_summary"]
