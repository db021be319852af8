"""What the world's servers share: the ports they listen on (with an error that says whose port it
is) and their background thread."""

from __future__ import annotations

import selectors
import socket
import threading
from abc import ABC, abstractmethod
from collections.abc import Mapping


def listen(kind: socket.SocketKind, host: str, port: int, vehicle: str, what: str) -> socket.socket:
    """A socket of ``kind`` bound to ``host:port`` (a TCP one listening), non-blocking; the error
    when the port is taken names the vehicle and ``what`` it was for."""
    s = socket.socket(socket.AF_INET, kind)
    if kind == socket.SOCK_STREAM:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        s.bind((host, port))
        if kind == socket.SOCK_STREAM:
            s.listen(1)
    except OSError as exc:
        s.close()
        proto = "TCP" if kind == socket.SOCK_STREAM else "UDP"
        raise OSError(exc.errno, f"{vehicle}: cannot listen on {proto} {host}:{port} for {what} "
                      f"({exc.strerror}): another physics server or simulator holds it; pick another "
                      "instance number") from exc
    s.setblocking(False)
    return s


def listen_all(kind: socket.SocketKind, host: str, ports: Mapping[str, int],
               what: str) -> dict[str, socket.socket]:
    """:func:`listen` on each vehicle's port; if one is taken, those already bound are closed."""
    out: dict[str, socket.socket] = {}
    try:
        for vehicle, port in ports.items():
            out[vehicle] = listen(kind, host, port, vehicle, what)
    except OSError:
        for s in out.values():
            s.close()
        raise
    return out


class ServingThread(ABC):
    """A server's background thread: ``_run`` serves ``_selector`` until ``_stopping`` is set."""

    def __init__(self, thread_name: str) -> None:
        self._selector = selectors.DefaultSelector()
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._thread_name = thread_name

    @abstractmethod
    def _run(self) -> None:
        """The thread's loop (the server's own)."""

    def _launch(self) -> None:
        self._thread = threading.Thread(target=self._run, name=self._thread_name, daemon=True)
        self._thread.start()

    def _halt(self) -> None:
        """Stop the thread (it finishes its pass: at most a select timeout)."""
        self._stopping.set()
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None
