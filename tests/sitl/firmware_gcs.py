"""A small synchronous ground station for the firmware tests: one UDP port that every firmware
vehicle sends to, replies to each vehicle at the address it sends from (told apart by system id),
every wait bounded by a timeout."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

ACCEPTED = mavlink2.MAV_RESULT_ACCEPTED


class SyncGcs:
    def __init__(self, port: int, sysid: int = 255, compid: int = 190) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", port))
        self.mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.parser = mavlink2.MAVLink(None)
        self.parser.robust_parsing = True
        self.addr: dict[int, tuple[str, int]] = {}
        self.last: dict[tuple[int, str], Any] = {}
        self.texts: list[tuple[int, str]] = []
        self.acks: list[Any] = []
        self._beat = 0.0

    def close(self) -> None:
        self.sock.close()

    def poll(self, timeout: float = 0.1) -> None:
        """Read whatever arrives within ``timeout`` seconds (and send our heartbeat each second)."""
        end = time.monotonic() + timeout
        while True:
            now = time.monotonic()
            if now >= self._beat:
                self._beat = now + 1.0
                for sysid in self.addr:
                    self.send(sysid, self.mav.heartbeat_encode(mavlink2.MAV_TYPE_GCS,
                                                               mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0))
            left = end - now
            if left <= 0:
                return
            self.sock.settimeout(left)
            try:
                data, addr = self.sock.recvfrom(4096)
            except TimeoutError:
                return
            for m in self.parser.parse_buffer(data) or []:
                if m.get_type() == "BAD_DATA":
                    continue
                src = m.get_srcSystem()
                if m.get_srcComponent() == 1:
                    self.addr.setdefault(src, addr)
                self.last[(src, m.get_type())] = m
                if m.get_type() == "STATUSTEXT":
                    self.texts.append((src, m.text))
                elif m.get_type() == "COMMAND_ACK":
                    self.acks.append(m)

    def wait(self, what: Callable[[], Any], timeout: float, why: str = "") -> Any:
        """Poll until ``what()`` is truthy; its value, or AssertionError after ``timeout`` s."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            got = what()
            if got:
                return got
            self.poll(0.1)
        raise AssertionError(f"timed out after {timeout:.0f} s waiting for {why or what}; "
                             f"last texts: {self.texts[-6:]}")

    def msg(self, sysid: int, mtype: str) -> Any:
        return self.last.get((sysid, mtype))

    def send(self, sysid: int, msg: Any) -> None:
        self.sock.sendto(msg.pack(self.mav), self.addr[sysid])

    def command(self, sysid: int, command: int, *params: float, timeout: float = 3.0) -> int:
        """Send COMMAND_LONG; the result of its COMMAND_ACK (-1 when none came)."""
        p = list(params) + [0.0] * (7 - len(params))
        start = len(self.acks)
        self.send(sysid, self.mav.command_long_encode(sysid, 1, command, 0, *p))
        try:
            ack = self.wait(lambda: next((a for a in self.acks[start:] if a.command == command
                                          and a.get_srcSystem() == sysid), None), timeout, "ack")
        except AssertionError:
            return -1
        return int(ack.result)

    def request_streams(self, sysid: int, rate_hz: int = 10) -> None:
        self.send(sysid, self.mav.request_data_stream_encode(sysid, 1, mavlink2.MAV_DATA_STREAM_ALL,
                                                             rate_hz, 1))

    def set_mode(self, sysid: int, mode: int) -> None:
        self.send(sysid, self.mav.set_mode_encode(sysid, mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode))

    def arm(self, sysid: int, mode: int, timeout: float) -> None:
        """Switch to ``mode`` and arm, retrying until the firmware accepts (pre-arm checks pass)."""
        def attempt() -> bool:
            self.set_mode(sysid, mode)
            return self.command(sysid, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 1, timeout=1.0) == ACCEPTED
        self.wait(attempt, timeout, f"sysid {sysid} to arm")

    def goto(self, sysid: int, lat: float, lon: float, alt: float) -> None:
        """A GUIDED position target (relative altitude)."""
        self.send(sysid, self.mav.set_position_target_global_int_encode(
            0, sysid, 1, mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b110111111000,
            int(round(lat * 1e7)), int(round(lon * 1e7)), alt, 0, 0, 0, 0, 0, 0, 0, 0))

    def position(self, sysid: int) -> tuple[float, float, float] | None:
        """(lat, lon, relative alt m) of the last GLOBAL_POSITION_INT."""
        m = self.msg(sysid, "GLOBAL_POSITION_INT")
        return None if m is None else (m.lat * 1e-7, m.lon * 1e-7, m.relative_alt * 1e-3)
