"""Parameters of one vehicle: PARAM_REQUEST_READ -> PARAM_VALUE, PARAM_SET confirmed by PARAM_VALUE.

Integer parameters travel in PARAM_VALUE's float field: ArduPilot casts them (``float(2)``), PX4
copies their bytes (MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE). ``Autopilot.param_bytewise``
says which; :func:`decode` and :func:`encode` do the conversion so callers see plain numbers.
"""

from __future__ import annotations

import asyncio
import math
import struct
import time
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from fleetctl.mavlink.link import Link, LinkError

M = mavlink2
PARAM_TIMEOUT = 1.0  # s per attempt until the link's round trips are known
PARAM_RETRIES = 3  # attempts of PARAM_TIMEOUT: the patience, filled with attempts at the link's
# retransmission timeout (as commands are)
_INT_TYPES = {M.MAV_PARAM_TYPE_UINT8: "<B", M.MAV_PARAM_TYPE_INT8: "<b", M.MAV_PARAM_TYPE_UINT16: "<H",
              M.MAV_PARAM_TYPE_INT16: "<h", M.MAV_PARAM_TYPE_UINT32: "<I", M.MAV_PARAM_TYPE_INT32: "<i"}


class ParamError(LinkError):
    """A parameter the vehicle does not have, or a PARAM_SET it did not confirm."""


class _Vehicle(Protocol):
    name: str
    sysid: int
    compid: int
    link: Link
    autopilot: Any


def _name(raw: Any) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return str(raw).split("\x00", 1)[0]


def decode(value: float, param_type: int, bytewise: bool) -> float:
    """The number a PARAM_VALUE carries."""
    fmt = _INT_TYPES.get(param_type)
    if not bytewise or fmt is None:
        return float(value)
    raw = struct.pack("<f", value)
    return float(struct.unpack(fmt, raw[: struct.calcsize(fmt)])[0])


def encode(value: float, param_type: int, bytewise: bool) -> float:
    """The float field of a PARAM_SET for ``value``."""
    fmt = _INT_TYPES.get(param_type)
    if not bytewise or fmt is None:
        return float(value)
    raw = struct.pack(fmt, int(round(value))).ljust(4, b"\x00")
    return float(struct.unpack("<f", raw)[0])


def _bytewise(v: _Vehicle) -> bool:
    return bool(getattr(v.autopilot, "param_bytewise", False))


async def read_param(v: _Vehicle, name: str, *, timeout: float = PARAM_TIMEOUT,
                     retries: int = PARAM_RETRIES) -> tuple[float, int] | None:
    """(value, MAV_PARAM_TYPE) of ``name``, or None when the vehicle does not answer (it has no
    such parameter: autopilots stay silent then)."""
    link = v.link
    msg = link.mav.param_request_read_encode(v.sysid, v.compid, name.encode(), -1)
    reply = await _ask(link, msg, v.sysid, name, timeout, retries)
    if reply is None:
        return None
    return decode(reply.param_value, reply.param_type, _bytewise(v)), reply.param_type


async def _ask(link: Link, msg: Any, sysid: int, name: str, timeout: float, retries: int) -> Any:
    """Send ``msg`` until a PARAM_VALUE of ``name`` answers it (None when none does) for
    ``retries x timeout`` in all, each attempt waiting the link's retransmission timeout
    (:class:`~fleetctl.mavlink.rtt.RoundTrip`, ``timeout`` until it is known)."""
    deadline = time.monotonic() + retries * timeout
    while (left := deadline - time.monotonic()) > 0:
        try:
            return await link.request(msg, sysid, "PARAM_VALUE", match=lambda m: _name(m.param_id) == name,
                                      timeout=min(link.rtt.timeout(timeout), left))
        except TimeoutError:
            continue
    return None


async def read_params(v: _Vehicle, names: list[str], **kw: Any) -> dict[str, float | None]:
    """name -> value (None = not answered) for every name, read in parallel."""
    got = await asyncio.gather(*(read_param(v, n, **kw) for n in names))
    return {n: (None if g is None else g[0]) for n, g in zip(names, got, strict=True)}


# PARAM_SET is sent this many times before an old value in the reply counts as a refusal: the first
# reply may be a late PARAM_VALUE answering an earlier read of the parameter (a PX4 carrier's
# RO_SPEED_LIM read back as its old 3 after being set to 1, once in CI, the firmware tests)
SET_ATTEMPTS = 2


async def set_param(v: _Vehicle, name: str, value: float, *, param_type: int | None = None,
                    timeout: float = PARAM_TIMEOUT, retries: int = PARAM_RETRIES) -> float:
    """Set ``name`` to ``value`` (PARAM_SET, resent until a PARAM_VALUE confirms the new value).
    The type is read first when not given. Raises :class:`ParamError`."""
    if param_type is None:
        cur = await read_param(v, name, timeout=timeout, retries=retries)
        if cur is None:
            raise ParamError(f"{v.name}: parameter {name} not answered (the firmware may not have it)")
        param_type = cur[1]
    link, bytewise = v.link, _bytewise(v)
    msg = link.mav.param_set_encode(v.sysid, v.compid, name.encode(), encode(value, param_type, bytewise),
                                    param_type)
    got = math.nan
    for _ in range(SET_ATTEMPTS):
        reply = await _ask(link, msg, v.sysid, name, timeout, retries)
        if reply is None:
            raise ParamError(f"{v.name}: PARAM_SET {name} = {value:g} not confirmed "
                             f"within {retries * timeout:g} s")
        got = decode(reply.param_value, reply.param_type, bytewise)
        if math.isclose(got, value, rel_tol=1e-6, abs_tol=1e-6):
            return got
    raise ParamError(f"{v.name}: {name} is {got:g} after setting it to {value:g} (the vehicle refused)")


__all__ = ["ParamError", "decode", "encode", "read_param", "read_params", "set_param"]
