"""A real `ssdo serve --socket` for the tests: started in a scratch folder, stopped after.

SSDO_BINARY names the executable (CTest sets it); default: build/ssdo of this clone.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import struct
import subprocess
import tempfile
import time
from pathlib import Path
from typing import List, Optional

REPO = Path(__file__).resolve().parents[2]
BINARY = Path(os.environ.get("SSDO_BINARY", REPO / "build" / "ssdo"))
FRAMES = REPO / "examples" / "frames"
#: A 640x360 Cycles frame with its camera sidecar (examples/frames).
FRAME = "cornell"
EXR_MAGIC = b"\x76\x2f\x31\x01"


class Service:
    """`ssdo serve` on a socket in a scratch folder: IN/ (the --allow folder, holding a copy
    of FRAME and its sidecar), OUT/ (--out). Killed (with its workers) by stop()."""

    def __init__(self, extra_args: List[str]) -> None:
        if not BINARY.is_file():
            raise FileNotFoundError(f"{BINARY}: no ssdo executable (build it, or set SSDO_BINARY)")
        self.root = Path(tempfile.mkdtemp(prefix="ssdo-py-"))
        self.input_dir = self.root / "in"
        self.out_dir = self.root / "out"
        self.input_dir.mkdir()
        self.out_dir.mkdir()
        for suffix in (".exr", ".camera.json"):
            shutil.copy(FRAMES / (FRAME + suffix), self.input_dir / (FRAME + suffix))
        self.frame = self.input_dir / (FRAME + ".exr")
        self.socket = str(self.root / "ssdo.sock")
        self.log = open(self.root / "serve.log", "w+")
        args = [str(BINARY), "serve", "--socket", self.socket, "-o", str(self.out_dir),
                "--allow", str(self.input_dir)] + extra_args
        self.process = subprocess.Popen(args, stdout=self.log, stderr=subprocess.STDOUT)
        self._wait_ready(20.0)

    def _wait_ready(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if self.process.poll() is not None:
                raise RuntimeError(f"ssdo serve exited with {self.process.returncode}: {self.log_text()}")
            if raw_ping(self.socket):
                return
            time.sleep(0.02)
        raise RuntimeError(f"ssdo serve not ready after {seconds} s: {self.log_text()}")

    def log_text(self) -> str:
        self.log.flush()
        return (self.root / "serve.log").read_text()

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.log.close()
        shutil.rmtree(self.root, ignore_errors=True)


def raw_ping(socket_path: str) -> Optional[dict]:
    """One ping over a fresh connection, or None when nobody answers (yet)."""
    try:
        with socket.socket(socket.AF_UNIX) as s:
            s.settimeout(2)
            s.connect(socket_path)
            body = b'{"op": "ping"}'
            s.sendall(struct.pack(">I", len(body)) + body)
            size = struct.unpack(">I", s.recv(4, socket.MSG_WAITALL))[0]
            return json.loads(s.recv(size, socket.MSG_WAITALL))
    except (OSError, ValueError, struct.error):
        return None


def wait_until(condition, seconds: float) -> bool:
    """Polls `condition` every 10 ms until it holds or `seconds` pass."""
    end = time.monotonic() + seconds
    while not condition():
        if time.monotonic() >= end:
            return bool(condition())
        time.sleep(0.01)
    return True


def exr_string_attributes(data: bytes) -> dict:
    """The string attributes of a single-part EXR header (OpenEXR file layout: magic,
    version, then name\\0 type\\0 size value ... up to an empty name)."""
    assert data[:4] == EXR_MAGIC, "not an EXR file"
    at, found = 8, {}
    while data[at] != 0:
        name_end = data.index(b"\0", at)
        type_end = data.index(b"\0", name_end + 1)
        (size,) = struct.unpack("<i", data[type_end + 1:type_end + 5])
        value = data[type_end + 5:type_end + 5 + size]
        if data[name_end + 1:type_end] == b"string":
            found[data[at:name_end].decode()] = value.decode()
        at = type_end + 5 + size
    return found
