"""MAVLink 2 signing on the simulated vehicles' side (independent of the controller package).

A vehicle with a key signs everything it sends (pymavlink's ``MAVLink.signing``, timestamps in
10 µs units since 2015-01-01, strictly increasing, at least the wall clock and at least the
highest valid timestamp heard) and accepts only correctly signed, fresh messages: unsigned ones
(RADIO_STATUS excepted, as ArduPilot and PX4 do), a wrong signature, or a timestamp not newer than
the last one accepted on that (sysid, compid, link_id) stream or more than 60 s behind the clock
are dropped and counted. SETUP_SIGNING sets the key (an all-zero key turns signing off).
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import hmac
import os
import time
from typing import Any

EPOCH_2015 = 1420070400
TICKS_PER_S = 100_000
MAX_BEHIND = 60 * TICKS_PER_S
ALLOW_UNSIGNED = frozenset({109})  # RADIO_STATUS

OK, UNSIGNED, BAD_SIGNATURE, REPLAY = 0, 1, 2, 3


def now_timestamp() -> int:
    return int((time.time() - EPOCH_2015) * TICKS_PER_S)


def parse_key(text: str, source: str) -> bytes:
    """A 32-byte key from 64 hex characters or base64 (the error never shows the value)."""
    s = text.strip()
    raw: bytes | None = None
    if len(s) == 64:
        try:
            raw = bytes.fromhex(s)
        except ValueError:
            raw = None
    if raw is None:
        alt = b"-_" if ("-" in s or "_" in s) else None
        try:
            raw = base64.b64decode(s + "=" * (-len(s) % 4), altchars=alt, validate=True)
        except (binascii.Error, ValueError):
            raw = None
    if raw is None or len(raw) != 32:
        raise ValueError(f"{source}: a signing key is 32 bytes as 64 hex characters or base64")
    return raw


def key_from_env(var: str) -> bytes:
    text = os.environ.get(var)
    if not text or not text.strip():
        raise ValueError(f"environment variable {var} (links.signing.key_env) is not set")
    return parse_key(text, f"environment variable {var}")


class SigningState:
    """One vehicle's key, outgoing timestamp and incoming streams."""

    def __init__(self, mav: Any) -> None:
        self.mav = mav
        self.key: bytes | None = None
        self._keyed: Any = None
        self.streams: dict[tuple[int, int, int], int] = {}
        self.rejected = {"unsigned": 0, "bad_signature": 0, "replay": 0}

    @property
    def active(self) -> bool:
        return self.key is not None

    def set_key(self, key: bytes | None, initial_timestamp: int = 0) -> None:
        """Sign with ``key`` from now on; None or all zeros turns signing off."""
        s = self.mav.signing
        if key is None or not any(key):
            self.key = self._keyed = None
            s.secret_key = None
            s.sign_outgoing = False
            self.streams.clear()
            return
        if len(key) != 32:
            raise ValueError("a signing key is 32 bytes")
        self.key = bytes(key)
        self._keyed = hashlib.sha256(self.key)
        self.streams.clear()
        s.secret_key = self.key
        s.link_id = 0
        s.sign_outgoing = True
        s.timestamp = max(int(s.timestamp), int(initial_timestamp), now_timestamp())

    def stamp(self) -> None:
        """Before packing: the timestamp is at least the clock (pymavlink adds 1 per packet)."""
        if self.key is not None:
            s = self.mav.signing
            now = now_timestamp()
            if now > s.timestamp:
                s.timestamp = now

    def check(self, buf: bytes | bytearray) -> int:
        if self._keyed is None:
            return OK
        n = len(buf)
        if buf[0] != 0xFD or not buf[2] & 0x01:
            if buf[0] == 0xFD and (buf[7] | (buf[8] << 8) | (buf[9] << 16)) in ALLOW_UNSIGNED:
                return OK
            self.rejected["unsigned"] += 1
            return UNSIGNED
        h = self._keyed.copy()
        h.update(memoryview(buf)[: n - 6])
        if n < 25 or not hmac.compare_digest(h.digest()[:6], buf[n - 6:]):
            self.rejected["bad_signature"] += 1
            return BAD_SIGNATURE
        ts = int.from_bytes(buf[n - 12 : n - 6], "little")
        stream = (buf[5], buf[6], buf[n - 13])
        last = self.streams.get(stream)
        if (last is not None and ts <= last) or ts + MAX_BEHIND < now_timestamp():
            self.rejected["replay"] += 1
            return REPLAY
        self.streams[stream] = ts
        s = self.mav.signing
        if ts > s.timestamp:
            s.timestamp = ts
        return OK


__all__ = ["SigningState", "key_from_env", "now_timestamp", "parse_key"]
