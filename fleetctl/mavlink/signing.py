"""MAVLink 2 message signing: the secret key, outgoing timestamps (persisted across restarts) and
the check of incoming signatures with replay protection.

Wire format (MAVLink 2 spec, "Message signing"): incompat flag 0x01, then 13 bytes after the CRC -
``link_id`` (1 byte), ``timestamp`` (48 bit, units of 10 µs since 2015-01-01 00:00 UTC) and
``signature`` = the first 6 bytes of SHA-256(key + header + payload + CRC + link_id + timestamp).

* :class:`SigningKey` holds the 32-byte secret; its ``repr``/``str`` never show it (only a short
  fingerprint of a hash, safe to log), and it is read from an environment variable as 64 hex
  characters or base64 (:meth:`SigningKey.from_env`).
* :class:`Signer` drives pymavlink's own signing of outgoing packets (``MAVLink.signing``) and keeps
  its timestamp strictly increasing, at least the wall clock, and persisted in a small JSON state
  file so that a restarted controller starts above every timestamp it sent before (a vehicle would
  reject it as a replay otherwise). The file holds a *reservation*: before a timestamp beyond the
  stored value is used, a value ``LEASE`` ahead is written, so even after a crash the next start
  (``max(now, stored + 1)``) is above everything sent.
* :class:`Verifier` checks an incoming packet: unsigned (RADIO_STATUS excepted, as ArduPilot and
  PX4 do), wrong signature, or replayed (timestamp not newer than the last one accepted on that
  (sysid, compid, link_id) stream, or more than 60 s behind our clock). The signature is checked
  *before* the stream's timestamp is touched, so forged packets cannot poison the replay state
  (pymavlink's own ``check_signature`` updates it first).
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import hmac
import json
import logging
import os
import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

EPOCH_2015 = 1420070400  # 2015-01-01T00:00:00Z, the signing timestamps' epoch
TICKS_PER_S = 100_000  # timestamp units: 10 µs
MAX_BEHIND = 60 * TICKS_PER_S  # a signed packet this far behind our clock is a replay
LEASE = 10 * TICKS_PER_S  # reserve this much timestamp ahead in the state file
SIGNATURE_LEN = 13
IFLAG_SIGNED = 0x01
MSG_ID_RADIO_STATUS = 109
ALLOW_UNSIGNED = frozenset({MSG_ID_RADIO_STATUS})  # a radio modem's own report: unsigned everywhere
ENV_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")

OK = 0
UNSIGNED = 1
BAD_SIGNATURE = 2
REPLAY = 3
REJECTION_KEYS = {UNSIGNED: "rejected_unsigned", BAD_SIGNATURE: "rejected_bad_signature",
                  REPLAY: "rejected_replay"}
KEYGEN_HINT = 'generate one with: python -c "import secrets; print(secrets.token_hex(32))"'


class SigningKeyError(ValueError):
    """A missing or malformed signing key (the message never contains the key)."""


def now_timestamp() -> int:
    """The current time as a signing timestamp (10 µs units since 2015-01-01 UTC)."""
    return int((time.time() - EPOCH_2015) * TICKS_PER_S)


class SigningKey:
    """A 32-byte MAVLink signing secret that does not show itself in logs, reprs or tracebacks."""

    __slots__ = ("_secret",)

    def __init__(self, secret: bytes) -> None:
        if not isinstance(secret, bytes | bytearray) or len(secret) != 32:
            raise SigningKeyError("a MAVLink signing key is 32 bytes")
        self._secret = bytes(secret)

    @property
    def secret(self) -> bytes:
        return self._secret

    @property
    def fingerprint(self) -> str:
        """16 hex characters of a hash of the key: safe to log, names the key's state file."""
        return hashlib.sha256(b"fleetctl-signing-key-id\0" + self._secret).hexdigest()[:16]

    @property
    def disables(self) -> bool:
        """An all-zero key: SETUP_SIGNING with it turns signing off (MAVLink spec)."""
        return not any(self._secret)

    def __repr__(self) -> str:
        return f"SigningKey(<hidden>, id={self.fingerprint})"

    __str__ = __repr__

    def __eq__(self, other: object) -> bool:
        return isinstance(other, SigningKey) and hmac.compare_digest(self._secret, other._secret)

    def __hash__(self) -> int:
        return hash(self.fingerprint)

    def __reduce__(self) -> Any:
        raise TypeError("a SigningKey is not serialisable")

    @classmethod
    def parse(cls, text: str, source: str = "the signing key") -> SigningKey:
        """From 64 hex characters or base64 of 32 bytes; :class:`SigningKeyError` names ``source``
        (never the value)."""
        s = text.strip()
        raw: bytes | None = None
        if len(s) == 64 and all(c in "0123456789abcdefABCDEF" for c in s):
            raw = bytes.fromhex(s)
        else:
            alt = b"-_" if ("-" in s or "_" in s) else None
            try:
                raw = base64.b64decode(s + "=" * (-len(s) % 4), altchars=alt, validate=True)
            except (binascii.Error, ValueError):
                raw = None
        if raw is None or len(raw) != 32:
            raise SigningKeyError(f"{source} is malformed: it must be 32 bytes written as 64 hex characters "
                                  f"or as base64 (it has {len(s)} characters); {KEYGEN_HINT}")
        return cls(raw)

    @classmethod
    def from_env(cls, var: str, environ: Any = None) -> SigningKey:
        """The key in environment variable ``var``; :class:`SigningKeyError` if unset or malformed."""
        env = os.environ if environ is None else environ
        text = env.get(var)
        if text is None or not text.strip():
            raise SigningKeyError(f"environment variable {var} (links.signing.key_env) is not set: "
                                  f"export the fleet's 32-byte signing key there; {KEYGEN_HINT}")
        return cls.parse(text, f"environment variable {var} (links.signing.key_env)")


def default_state_path(key: SigningKey) -> Path:
    """``$XDG_STATE_HOME/fleetctl/signing-<key id>.json`` (default ``~/.local/state/...``)."""
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "fleetctl" / f"signing-{key.fingerprint}.json"


def state_path(key: SigningKey, where: str | Path | None) -> Path:
    """The state file for ``key``: ``where`` itself, ``where/signing-<id>.json`` when it is a
    directory (e.g. the run folder), or the default location when None."""
    if where is None:
        return default_state_path(key)
    p = Path(where)
    return p / f"signing-{key.fingerprint}.json" if p.is_dir() else p


class TimestampStore:
    """The highest timestamp reserved with a key, in a small JSON file (atomic replace)."""

    def __init__(self, path: Path, key_id: str) -> None:
        self.path = path
        self.key_id = key_id

    def load(self) -> int:
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
            return int(data.get("timestamp", 0))
        except FileNotFoundError:
            return 0
        except (OSError, ValueError, TypeError, AttributeError) as exc:
            log.warning("signing state %s unreadable (%s); starting from the clock", self.path, exc)
            return 0

    def save(self, timestamp: int) -> bool:
        """Write ``max(stored, timestamp)``; False (and a warning) when the file cannot be written."""
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            value = max(timestamp, self.load())
            tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
            tmp.write_text(json.dumps({"key_id": self.key_id, "timestamp": value}), encoding="utf-8")
            os.replace(tmp, self.path)
            return True
        except OSError as exc:
            log.warning("signing state %s cannot be written (%s): a restart may be rejected as a replay",
                        self.path, exc)
            return False


class Signer:
    """Signs everything a pymavlink ``MAVLink`` codec packs, with a strictly increasing timestamp that
    is at least the wall clock and (with a store) above anything sent before a restart."""

    def __init__(self, mav: Any, key: SigningKey, link_id: int = 0,
                 store: TimestampStore | None = None) -> None:
        if not 0 <= link_id <= 255:
            raise ValueError(f"link_id must be 0..255, got {link_id}")
        self.mav = mav
        self.key = key
        self.store = store
        persisted = store.load() if store is not None else 0
        self.start = max(now_timestamp(), persisted + 1)
        s = mav.signing
        s.secret_key = key.secret
        s.link_id = link_id
        s.sign_outgoing = True
        s.timestamp = self.start
        s.allow_unsigned_callback = None
        self.reserved = 0
        self._reserve(self.start)

    def _reserve(self, ts: int) -> None:
        if self.store is None:
            self.reserved = 1 << 62
            return
        self.reserved = ts + LEASE
        self.store.save(self.reserved)

    @property
    def timestamp(self) -> int:
        """The timestamp the next packet will carry (before :meth:`stamp` moves it to the clock)."""
        return int(self.mav.signing.timestamp)

    def stamp(self) -> None:
        """Call before packing a message: moves the timestamp up to the clock, renews the reservation."""
        s = self.mav.signing
        now = now_timestamp()
        if now > s.timestamp:
            s.timestamp = now
        if s.timestamp >= self.reserved:
            self._reserve(s.timestamp)

    def seen(self, timestamp: int) -> None:
        """A valid incoming timestamp: the spec has us send no lower than the highest seen."""
        s = self.mav.signing
        if timestamp > s.timestamp:
            s.timestamp = timestamp

    def close(self) -> None:
        """Persist the last timestamp used (the next start is above it)."""
        if self.store is not None:
            self.store.save(self.mav.signing.timestamp)


class Verifier:
    """Checks incoming MAVLink 2 packets (raw bytes) against ``key``; see the module docstring."""

    def __init__(self, key: SigningKey, clock: Callable[[], int] | None = None,
                 seen: Callable[[int], None] | None = None) -> None:
        self._keyed = hashlib.sha256(key.secret)  # the key absorbed once; copied per packet
        self._seen = seen  # told every accepted timestamp (the spec: send no lower than seen)
        self.streams: dict[tuple[int, int, int], int] = {}  # (sysid, compid, link_id) -> last timestamp
        self.max_behind = MAX_BEHIND
        self._clock = clock or now_timestamp  # the wall clock (not what other senders pulled us up to)

    def check(self, buf: bytes | bytearray) -> int:
        """:data:`OK`, :data:`UNSIGNED`, :data:`BAD_SIGNATURE` or :data:`REPLAY`; records the stream's
        timestamp only for an accepted packet."""
        if buf[0] != 0xFD:
            return UNSIGNED  # MAVLink 1 cannot carry a signature
        if not buf[2] & IFLAG_SIGNED:
            msgid = buf[7] | (buf[8] << 8) | (buf[9] << 16)
            return OK if msgid in ALLOW_UNSIGNED else UNSIGNED
        n = len(buf)
        if n < 12 + SIGNATURE_LEN:
            return BAD_SIGNATURE
        h = self._keyed.copy()
        h.update(memoryview(buf)[: n - 6])
        if not hmac.compare_digest(h.digest()[:6], buf[n - 6:]):
            return BAD_SIGNATURE
        ts = int.from_bytes(buf[n - 12 : n - 6], "little")
        stream = (buf[5], buf[6], buf[n - 13])
        last = self.streams.get(stream)
        if last is not None and ts <= last:
            return REPLAY
        if ts + self.max_behind < self._clock():
            return REPLAY
        self.streams[stream] = ts
        if self._seen is not None:
            self._seen(ts)
        return OK


__all__ = [
    "ALLOW_UNSIGNED",
    "BAD_SIGNATURE",
    "OK",
    "REJECTION_KEYS",
    "REPLAY",
    "UNSIGNED",
    "Signer",
    "SigningKey",
    "SigningKeyError",
    "TimestampStore",
    "Verifier",
    "default_state_path",
    "now_timestamp",
    "state_path",
]
