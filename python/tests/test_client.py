"""ssdo_client against a real `ssdo serve --socket` (tests/service.py starts it)."""

from __future__ import annotations

import json
import os
import socket
import sys
import threading
import time
import unittest
from pathlib import Path
from typing import List

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # ssdo_client without installing

from service import EXR_MAGIC, FRAME, FRAMES, Service, exr_string_attributes, wait_until  # noqa: E402
from ssdo_client import PROTOCOL_VERSION, Client, ReplyTimeout, ServiceError, TransportError  # noqa: E402

# Cheap frames: GTAO low, AO only, one single-threaded worker.
FAST = ["--method", "gtao", "--preset", "low", "--terms", "ao", "--jobs", "1"]


class ClientTest(unittest.TestCase):
    service: Service

    @classmethod
    def setUpClass(cls) -> None:
        cls.service = Service(FAST)

    @classmethod
    def tearDownClass(cls) -> None:
        cls.service.stop()

    def client(self) -> Client:
        c = Client(self.service.socket, timeout=60)
        self.addCleanup(c.close)
        return c

    def test_ping_gives_version_and_protocol(self) -> None:
        pong = self.client().check_protocol()
        self.assertEqual(pong["op"], "ping")
        self.assertTrue(pong["version"].startswith("ssdo "), pong)
        self.assertEqual(pong["protocol"], PROTOCOL_VERSION)

    def test_stats_counts_frames(self) -> None:
        c = self.client()
        before = c.stats()
        for key in ("frames_done", "frames_failed", "queue_depth", "queue_capacity", "in_flight", "workers",
                    "clients", "uptime_s", "mean_frame_ms", "workers_replaced", "frames_skipped"):
            self.assertIn(key, before)
        self.assertEqual(before["workers"], 1)
        self.assertEqual(before["queue_capacity"], 64)
        self.assertGreaterEqual(before["clients"], 1)
        c.process(self.service.frame)
        self.assertEqual(c.stats()["frames_done"], before["frames_done"] + 1)

    def test_path_request_writes_the_output_under_out(self) -> None:
        r = self.client().process(self.service.frame, output=str(self.service.out_dir / "path.ssdo.exr"))
        self.assertEqual((r.width, r.height), (640, 360))
        self.assertIn("ao", r.terms)
        self.assertIsNone(r.data)
        self.assertEqual(Path(r.output), self.service.out_dir / "path.ssdo.exr")
        self.assertEqual(Path(r.output).read_bytes()[:4], EXR_MAGIC)
        for key in ("read_ms", "compute_ms", "write_ms", "worker_ms", "total_ms"):
            self.assertGreaterEqual(r.times[key], 0.0)
        self.assertGreaterEqual(r.times["total_ms"], r.times["compute_ms"])

    def test_frame_options_reach_the_frame(self) -> None:
        r = self.client().process(self.service.frame, terms="ao,composite", env_constant=0.5)
        self.assertIn("composite", r.terms)
        header = exr_string_attributes(Path(r.output).read_bytes()[:65536])
        options = json.loads(header["ssdo/options"])
        self.assertEqual(options["terms"], "ao,composite")
        self.assertEqual(options["env-constant"], 0.5)
        self.assertEqual(options["preset"], "low")  # the service's own option
        self.assertTrue(header["ssdo/version"].startswith("ssdo "))

    def test_path_outside_allow_is_forbidden(self) -> None:
        c = self.client()
        with self.assertRaises(ServiceError) as caught:
            c.process(FRAMES / (FRAME + ".exr"))
        self.assertEqual(caught.exception.code, "forbidden")
        self.assertIn(str(FRAMES / (FRAME + ".exr")), caught.exception.message)
        self.assertEqual(c.ping()["op"], "ping")  # the client reconnects after an error

    def test_bad_option_is_a_bad_request_naming_it(self) -> None:
        with self.assertRaises(ServiceError) as caught:
            self.client().process(self.service.frame, preset="extreme")
        self.assertEqual(caught.exception.code, "bad_request")
        self.assertIn("preset", caught.exception.message)

    def test_inline_round_trip(self) -> None:
        data = (FRAMES / (FRAME + ".exr")).read_bytes()
        sidecar = json.loads((FRAMES / (FRAME + ".camera.json")).read_text())
        r = self.client().process(data, name="sent", sidecar=sidecar)
        self.assertIsNone(r.output)
        self.assertIsNotNone(r.data)
        assert r.data is not None
        self.assertEqual(r.data[:4], EXR_MAGIC)
        self.assertEqual(len(r.data), r.reply["inline_size"])
        self.assertEqual((r.width, r.height), (640, 360))
        self.assertFalse((self.service.out_dir / "sent.ssdo.exr").exists())  # nothing kept
        self.assertIn("ssdo/options", exr_string_attributes(r.data))

    def test_files_the_options_name_are_the_clients(self) -> None:
        # A relative --camera is this process's file: sent as an absolute path by path, and
        # read here and sent as the sidecar with inline bytes.
        frame = Path(self.service.frame)
        camera = frame.with_name(FRAME + ".camera.json")
        cwd = os.getcwd()
        os.chdir(frame.parent)
        self.addCleanup(os.chdir, cwd)
        r = self.client().process(frame.name, camera=camera.name)
        options = json.loads(exr_string_attributes(Path(r.output).read_bytes()[:65536])["ssdo/options"])
        self.assertEqual(options["camera"], str(camera))
        sent = self.client().process(frame.read_bytes(), name="sent_camera", camera=camera.name)
        self.assertEqual((sent.width, sent.height), (640, 360))

    def test_damaged_inline_frame_fails_with_its_reason(self) -> None:
        with self.assertRaises(ServiceError) as caught:
            self.client().process(b"not an EXR file", name="junk")
        self.assertEqual(caught.exception.code, "frame_failed")
        self.assertIn("junk", caught.exception.message)
        self.assertIn("times", caught.exception.reply)

    def test_unreachable_socket_and_timeout(self) -> None:
        with self.assertRaises(TransportError):
            Client(str(self.service.root / "nobody.sock"), timeout=2).ping()
        # A peer that accepts and never answers: the client gives up after its timeout.
        silent_path = str(self.service.root / "silent.sock")
        with socket.socket(socket.AF_UNIX) as silent:
            silent.bind(silent_path)
            silent.listen(1)
            start = time.monotonic()
            with self.assertRaises(ReplyTimeout):
                Client(silent_path, timeout=0.3).ping()
            self.assertLess(time.monotonic() - start, 5)


class BusyQueueTest(unittest.TestCase):
    """--queue 1 --jobs 1: one frame computing, one waiting, the next one refused."""

    def test_full_queue_answers_busy(self) -> None:
        service = Service(FAST + ["--queue", "1", "--frame-timeout", "2", "--retries", "0"])
        self.addCleanup(service.stop)
        errors: List[str] = []

        def slow_frame(output: str) -> None:
            # The ray-marched oracle takes far longer than --frame-timeout: the worker is
            # killed after 2 s and the frame fails; it holds the worker until then. Each
            # request its own output (one being computed is refused to another request).
            try:
                Client(service.socket, timeout=30).process(
                    service.frame, output=str(service.out_dir / output), method="raymarch", preset="ultra"
                )
            except ServiceError as e:
                errors.append(e.code)

        monitor = Client(service.socket, timeout=10)
        self.addCleanup(monitor.close)
        first = threading.Thread(target=slow_frame, args=("first.exr",))
        first.start()
        self.assertTrue(wait_until(lambda: monitor.stats()["in_flight"] == 1, 10), service.log_text())
        second = threading.Thread(target=slow_frame, args=("second.exr",))
        second.start()
        self.assertTrue(wait_until(lambda: monitor.stats()["queue_depth"] == 1, 10), service.log_text())
        with self.assertRaises(ServiceError) as caught:
            Client(service.socket, timeout=10).process(service.frame)
        self.assertEqual(caught.exception.code, "busy")
        self.assertIn("queue is full", caught.exception.message)
        first.join(30)
        second.join(30)
        self.assertEqual(errors, ["frame_failed", "frame_failed"])
        self.assertEqual(monitor.stats()["workers_replaced"], 2)


if __name__ == "__main__":
    unittest.main()
