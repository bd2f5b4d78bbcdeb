"""A client of the ssdo service socket (``ssdo serve --socket PATH``).

The wire format (docs/service.md, "Wire protocol"): every message, both ways, is a 4-byte
big-endian unsigned length N followed by N bytes of UTF-8 JSON (one object). A message
whose JSON holds ``"inline_size": K`` (K > 0) is followed directly by K raw bytes (an EXR
file). One connection carries any number of requests, one at a time; every request gets
exactly one reply.
"""

from __future__ import annotations

import json
import os
import select
import socket
import struct
import time
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Union

#: The protocol revision this client speaks: the ``protocol`` field of the ``ping`` reply.
PROTOCOL_VERSION = 1

#: Largest reply header accepted, bytes (the service's replies are a few hundred bytes).
MAX_REPLY_HEADER_BYTES = 1 << 20

_LENGTH = struct.Struct(">I")

# The frame options whose values are file paths (docs/options.md: --camera, --env).
_FILE_OPTIONS = ("camera", "env")

JsonObject = Dict[str, Any]
PathLike = Union[str, "os.PathLike[str]"]


class SsdoError(Exception):
    """Base class of every error this client raises."""


class ServiceError(SsdoError):
    """The service answered ``{"ok": false, "code": ..., "error": ...}``.

    Attributes:
        code: the service's error code (``bad_request``, ``too_large``, ``forbidden``,
            ``busy``, ``timeout``, ``frame_failed``, ``internal``; docs/service.md, "Errors").
        message: the service's message, naming the field or file and the reason.
        reply: the whole reply (``times`` and ``error_file`` for ``frame_failed``).
    """

    def __init__(self, code: str, message: str, reply: JsonObject) -> None:
        super().__init__(f"{code}: {message}")
        self.code = code
        self.message = message
        self.reply = reply


class TransportError(SsdoError, ConnectionError):
    """The socket could not be reached, or closed or broke in the middle of an exchange."""


class ReplyTimeout(SsdoError, TimeoutError):
    """No complete reply within the client's timeout."""


class ProtocolMismatchError(SsdoError):
    """The service speaks another protocol revision than :data:`PROTOCOL_VERSION`."""

    def __init__(self, service_protocol: int, service_version: str) -> None:
        super().__init__(
            f"the service ({service_version}) speaks protocol {service_protocol}; "
            f"this client speaks protocol {PROTOCOL_VERSION}: use a client of the service's version"
        )
        self.service_protocol = service_protocol
        self.service_version = service_version


@dataclass
class ProcessResult:
    """The reply to a successful ``process`` request.

    Attributes:
        terms: the terms written, e.g. ``["ao", "bent_normal", "confidence", "composite"]``.
        width: the frame's width in pixels.
        height: the frame's height in pixels.
        times: milliseconds: ``read_ms``, ``compute_ms``, ``write_ms`` (inside the worker),
            ``worker_ms`` (the worker's whole handling) and ``total_ms`` (queueing included).
        output: the output EXR's path on the service's side (``reply="path"``), else None.
        data: the output EXR's bytes (``reply="inline"``), else None.
        reply: the whole reply header.
    """

    terms: List[str]
    width: int
    height: int
    times: Dict[str, float]
    output: Optional[str] = None
    data: Optional[bytes] = None
    reply: JsonObject = field(default_factory=dict)


def option_key(name: str) -> str:
    """The option key of a Python keyword: ``ssdo_method`` -> ``ssdo-method``."""
    return name.replace("_", "-")


class Client:
    """One connection to ``ssdo serve --socket PATH``, opened on first use.

    Requests go one at a time over the connection. After an error reply the connection is
    closed (the service closes it after some errors) and the next request opens a new one.

    Args:
        socket_path: the service's socket.
        timeout: seconds to wait for each reply (a frame's computation included), and to
            connect and send. ``None`` waits forever.

    Use as a context manager, or call :meth:`close`::

        with Client("/tmp/ssdo.sock", timeout=60) as c:
            print(c.ping()["version"])
            result = c.process("/data/in/shot.0001.exr", terms="ao,ssdo", preset="low")
            print(result.output, result.times["total_ms"])
    """

    def __init__(self, socket_path: PathLike, timeout: Optional[float] = 600.0) -> None:
        self.socket_path = os.fspath(socket_path)
        self.timeout = timeout
        self._sock: Optional[socket.socket] = None

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Closes the connection (the next request opens a new one)."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def ping(self) -> JsonObject:
        """``{"ok": true, "op": "ping", "version": "ssdo 0.1.0", "protocol": 1}``."""
        return self.request({"op": "ping"})[0]

    def check_protocol(self) -> JsonObject:
        """Pings and raises :class:`ProtocolMismatchError` when the service's protocol
        revision is not :data:`PROTOCOL_VERSION` (a service without the field speaks 1)."""
        pong = self.ping()
        protocol = int(pong.get("protocol", 1))
        if protocol != PROTOCOL_VERSION:
            raise ProtocolMismatchError(protocol, str(pong.get("version", "?")))
        return pong

    def stats(self) -> JsonObject:
        """The service's counters: ``frames_done``, ``frames_failed``, ``frames_skipped``,
        ``queue_depth``, ``queue_capacity``, ``in_flight``, ``mean_frame_ms``, ``workers``,
        ``workers_replaced``, ``clients``, ``uptime_s``."""
        return self.request({"op": "stats"})[0]

    def process(
        self,
        source: Union[PathLike, bytes],
        *,
        name: Optional[str] = None,
        sidecar: Optional[Mapping[str, Any]] = None,
        output: Optional[str] = None,
        reply: Optional[str] = None,
        options: Optional[Mapping[str, Any]] = None,
        **frame_options: Any,
    ) -> ProcessResult:
        """Computes one frame.

        Args:
            source: the frame's path, which the service reads itself (it must lie under
                one of its ``--allow`` folders; a relative path is made absolute here), or
                the bytes of an EXR file, sent after the request.
            name: inline frames: the file stem (``[A-Za-z0-9._-]``, default ``inline``).
            sidecar: inline frames: the camera sidecar object (``NAME.camera.json``).
            output: an output path under the service's ``--out`` (path replies only).
            reply: ``"path"`` (the service keeps the output and returns its path) or
                ``"inline"`` (the output's bytes come back in :attr:`ProcessResult.data`,
                nothing is kept). Default: ``"inline"`` for bytes, ``"path"`` for a path.
            options: frame options as the service spells them (docs/options.md), e.g.
                ``{"ssdo-method": "oracle"}``.
            **frame_options: more frame options as keywords, ``_`` for ``-``:
                ``method="gtao", preset="low", terms="ao,ssdo", env_constant=0.5``.

        Raises:
            ServiceError: the service refused the request or the frame failed.
            ReplyTimeout: no reply within the timeout.
            TransportError: the socket could not be reached or broke.
        """
        request: JsonObject = {"op": "process"}
        payload = b""
        if isinstance(source, (bytes, bytearray, memoryview)):
            payload = bytes(source)
            if name is not None:
                request["name"] = name
            if sidecar is not None:
                request["sidecar"] = dict(sidecar)
        else:
            request["input"] = os.path.abspath(os.fspath(source))
        if output is not None:
            request["output"] = output
        request["reply"] = reply or ("inline" if payload else "path")
        merged = dict(options or {})
        merged.update({option_key(k): v for k, v in frame_options.items()})
        # Files the options name are this process's: absolute paths (the service resolves
        # relative ones against its own folder); with inline bytes the service reads no
        # file of ours, so a camera file goes as the sidecar.
        for key in _FILE_OPTIONS:
            value = merged.get(key)
            if not value:
                continue
            path = os.path.abspath(os.fspath(value))
            if payload and key == "camera":
                if "sidecar" not in request:
                    with open(path, "r", encoding="utf-8") as f:
                        request["sidecar"] = json.load(f)
                del merged[key]
            else:
                merged[key] = path
        if merged:
            request["options"] = merged
        header, data = self.request(request, payload)
        return ProcessResult(
            terms=list(header.get("terms", [])),
            width=int(header.get("width", 0)),
            height=int(header.get("height", 0)),
            times=dict(header.get("times", {})),
            output=header.get("output"),
            data=data if header.get("inline_size") else None,
            reply=header,
        )

    def request(self, message: JsonObject, payload: bytes = b"") -> "tuple[JsonObject, bytes]":
        """Sends one request (``payload``: inline bytes after it; ``inline_size`` is set
        here) and returns the reply and its inline bytes. Raises :class:`ServiceError` for
        an ``"ok": false`` reply."""
        message = dict(message)
        if payload:
            message["inline_size"] = len(payload)
        deadline = None if self.timeout is None else time.monotonic() + self.timeout
        sock = self._connection(deadline)
        try:
            body = json.dumps(message).encode("utf-8")
            self._send(sock, _LENGTH.pack(len(body)) + body, deadline)
            if payload:
                try:
                    self._send(sock, payload, deadline)
                except TransportError:
                    pass  # refused before the payload was read: the reply says why
            reply = self._read_reply(sock, deadline)
            data = self._read_exact(sock, int(reply["inline_size"]), deadline) if reply.get("inline_size") else b""
        except BaseException:
            self.close()  # the stream may be out of step
            raise
        if not reply.get("ok", False):
            self.close()
            raise ServiceError(str(reply.get("code", "unknown")), str(reply.get("error", "")), reply)
        return reply, data

    def _connection(self, deadline: Optional[float]) -> socket.socket:
        # Between requests the service sends nothing; anything readable now is its
        # "timeout" answer to a connection idle past --client-timeout, or its close.
        if self._sock is not None and select.select([self._sock], [], [], 0)[0]:
            self.close()
        if self._sock is None:
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            try:
                sock.settimeout(_left(deadline))
                sock.connect(self.socket_path)
            except socket.timeout as e:
                sock.close()
                raise ReplyTimeout(f"{self.socket_path}: cannot connect within {self.timeout} s") from e
            except OSError as e:
                sock.close()
                raise TransportError(f"{self.socket_path}: cannot connect: {e.strerror or e}") from e
            self._sock = sock
        return self._sock

    def _send(self, sock: socket.socket, data: bytes, deadline: Optional[float]) -> None:
        try:
            sock.settimeout(_left(deadline))
            sock.sendall(data)
        except socket.timeout as e:
            raise ReplyTimeout(f"{self.socket_path}: cannot send the request within {self.timeout} s") from e
        except OSError as e:
            raise TransportError(f"{self.socket_path}: sending failed: {e.strerror or e}") from e

    def _read_reply(self, sock: socket.socket, deadline: Optional[float]) -> JsonObject:
        (size,) = _LENGTH.unpack(self._read_exact(sock, 4, deadline))
        if size > MAX_REPLY_HEADER_BYTES:
            raise TransportError(f"{self.socket_path}: a reply header of {size} bytes (not the ssdo protocol?)")
        try:
            reply = json.loads(self._read_exact(sock, size, deadline).decode("utf-8"))
        except ValueError as e:
            raise TransportError(f"{self.socket_path}: the reply is not JSON: {e}") from e
        if not isinstance(reply, dict):
            raise TransportError(f"{self.socket_path}: the reply is not a JSON object")
        return reply

    def _read_exact(self, sock: socket.socket, size: int, deadline: Optional[float]) -> bytes:
        chunks = bytearray()
        while len(chunks) < size:
            try:
                sock.settimeout(_left(deadline))
                chunk = sock.recv(min(size - len(chunks), 1 << 20))
            except socket.timeout as e:
                raise ReplyTimeout(f"{self.socket_path}: no complete reply within {self.timeout} s") from e
            except OSError as e:
                raise TransportError(f"{self.socket_path}: receiving failed: {e.strerror or e}") from e
            if not chunk:
                raise TransportError(f"{self.socket_path}: the service closed the connection")
            chunks += chunk
        return bytes(chunks)


def _left(deadline: Optional[float]) -> Optional[float]:
    """Seconds until ``deadline`` (None: no deadline); a passed deadline gives a tiny
    positive timeout, so the next blocking call times out instead of blocking."""
    if deadline is None:
        return None
    return max(deadline - time.monotonic(), 1e-3)
