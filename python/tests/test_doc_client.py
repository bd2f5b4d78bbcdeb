"""docs/service.md is enough to write a client: its example script, run as printed (only
SOCKET and FRAME set), and a second raw client written from the page alone, both against
the real service. Standard library only; ssdo_client is not used here."""

from __future__ import annotations

import json
import re
import socket
import struct
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

from service import EXR_MAGIC, REPO, Service

DOC = REPO / "docs" / "service.md"


def doc_example() -> str:
    """The Python block of docs/service.md's "A client in Python" section."""
    text = DOC.read_text()
    section = text[text.index("### A client in Python"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


class DocExampleTest(unittest.TestCase):
    service: Service

    @classmethod
    def setUpClass(cls) -> None:
        cls.service = Service(["--method", "gtao", "--preset", "low", "--jobs", "1"])

    @classmethod
    def tearDownClass(cls) -> None:
        cls.service.stop()

    def test_the_printed_script_processes_by_path_and_inline(self) -> None:
        script, n = re.subn(r'^SOCKET, FRAME = .*$', f"SOCKET, FRAME = {self.service.socket!r}, "
                            f"{str(self.service.frame)!r}", doc_example(), flags=re.M)
        self.assertEqual(n, 1, "the example no longer sets SOCKET, FRAME on one line")
        with tempfile.TemporaryDirectory() as cwd:
            run = subprocess.run([sys.executable, "-c", script], cwd=cwd, capture_output=True, text=True,
                                 timeout=120)
            self.assertEqual(run.returncode, 0, run.stderr)
            lines = run.stdout.splitlines()
            self.assertEqual(len(lines), 2, run.stdout)
            self.assertIn("'ok': True", lines[0])
            self.assertIn(f"'output': '{self.service.out_dir / 'cornell.ssdo.exr'}'", lines[0])
            self.assertIn("'inline_size':", lines[1])
            self.assertEqual((Path(cwd) / "shot.ssdo.exr").read_bytes()[:4], EXR_MAGIC)

    def test_a_raw_client_from_the_page(self) -> None:
        # Framing: 4-byte big-endian length + UTF-8 JSON; inline bytes after the header.
        def send(s: socket.socket, obj: dict, payload: bytes = b"") -> None:
            if payload:
                obj["inline_size"] = len(payload)
            body = json.dumps(obj).encode("utf-8")
            s.sendall(struct.pack(">I", len(body)) + body + payload)

        def exactly(s: socket.socket, n: int) -> bytes:
            data = b""
            while len(data) < n:
                chunk = s.recv(n - len(data))
                self.assertTrue(chunk, "the service closed the connection")
                data += chunk
            return data

        def receive(s: socket.socket) -> tuple:
            (n,) = struct.unpack(">I", exactly(s, 4))
            reply = json.loads(exactly(s, n).decode("utf-8"))
            return reply, exactly(s, reply.get("inline_size", 0))

        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
            s.settimeout(60)
            s.connect(self.service.socket)
            send(s, {"op": "ping", "id": 7})
            pong, _ = receive(s)
            self.assertEqual((pong["ok"], pong["protocol"], pong["id"]), (True, 1, 7))
            send(s, {"op": "stats"})
            self.assertEqual(receive(s)[0]["workers"], 1)
            # An error that keeps the connection open, then an inline frame on the same one.
            send(s, {"op": "process", "input": "/etc/hostname", "id": "x"})
            refused, _ = receive(s)
            self.assertEqual((refused["ok"], refused["code"], refused["id"]), (False, "forbidden", "x"))
            frame = self.service.frame.read_bytes()
            sidecar = json.loads(self.service.frame.with_suffix(".camera.json").read_text())
            send(s, {"op": "process", "name": "raw", "reply": "inline", "sidecar": sidecar,
                     "options": {"terms": "ao"}}, frame)
            reply, exr = receive(s)
            self.assertTrue(reply["ok"], reply)
            self.assertEqual((reply["width"], reply["height"]), (640, 360))
            self.assertEqual(len(exr), reply["inline_size"])
            self.assertEqual(exr[:4], EXR_MAGIC)
            # A request the page says closes the connection: an unknown field.
            send(s, {"op": "ping", "colour": "blue"})
            bad, _ = receive(s)
            self.assertEqual(bad["code"], "bad_request")
            self.assertIn("colour", bad["error"])
            self.assertEqual(s.recv(1), b"")


if __name__ == "__main__":
    unittest.main()
