"""The Python client against the real server (standard library only).

    STROKELAB_BINARY=build/release/strokelab python3 -m unittest -v test_strokelab_client

Starts `strokelab serve --port 0` twice on temporary databases: an open one with two in-process
workers (a small sweep end to end, paging, filters, the example script, error replies), and one
with a token file and no workers (roles, and cancelling a job that stays queued).
"""

import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from strokelab_client import Client, StrokelabError  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
BINARY = os.environ.get("STROKELAB_BINARY") or os.path.join(HERE, "..", "..", "build", "release", "strokelab")
SUBMIT_TOKEN = "python-test-submit-token-0123456789"
READ_TOKEN = "python-test-read-token-0123456789"

# Eq. 1 frequencies from 5 Hz (20 of them, up to 7.3 Hz) x 4 amplitudes 0.3 .. 0.6 V: the stop is
# hit at the upper amplitudes, so thresholds exist.
SMALL_SWEEP = {
    "kind": "sweep",
    "name": "python client test",
    "model": "paper",
    "grid": {"frequency_hz": {"from": 5, "points": 20, "spacing": "eq1"},
             "amplitude_v": {"from": 0.3, "to": 0.6, "points": 4}},
}


class Server:
    """`strokelab serve --port 0` on a temporary database; the port is read from its stderr line
    "strokelab serving http://127.0.0.1:PORT (database ...)"."""

    def __init__(self, directory, name, *options):
        self.log_path = os.path.join(directory, name + ".log")
        self.log = open(self.log_path, "w")
        self.process = subprocess.Popen(
            [BINARY, "serve", "--port", "0", "--db", os.path.join(directory, name + ".db"), "--quiet", *options],
            stdout=subprocess.DEVNULL, stderr=self.log)
        deadline = time.monotonic() + 30
        self.url = None
        while self.url is None:
            with open(self.log_path) as f:
                match = re.search(r"strokelab serving (http://127\.0\.0\.1:\d+) ", f.read())
            if match:
                self.url = match.group(1)
            elif self.process.poll() is not None:
                raise RuntimeError(f"the server exited ({self.process.returncode}): {self.log_text()}")
            elif time.monotonic() > deadline:
                self.stop()
                raise RuntimeError(f"the server did not print its address within 30 s: {self.log_text()}")
            else:
                time.sleep(0.05)

    def log_text(self):
        with open(self.log_path) as f:
            return f.read()[-2000:]

    def stop(self):
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.log.close()


def setUpModule():
    global TMP, OPEN, SECURED
    if not os.access(BINARY, os.X_OK):
        raise unittest.SkipTest(f"no strokelab binary at {BINARY} (set STROKELAB_BINARY)")
    TMP = tempfile.mkdtemp(prefix="strokelab-python-")
    with open(os.path.join(TMP, "tokens"), "w") as f:
        f.write(f"# role token\nsubmit {SUBMIT_TOKEN}\nread {READ_TOKEN}\n")
    OPEN = Server(TMP, "open", "--workers", "2")
    try:
        SECURED = Server(TMP, "secured", "--workers", "0", "--token-file", os.path.join(TMP, "tokens"))
    except Exception:
        OPEN.stop()
        raise


def tearDownModule():
    OPEN.stop()
    SECURED.stop()
    shutil.rmtree(TMP, ignore_errors=True)


class SweepEndToEnd(unittest.TestCase):
    """One small sweep, submitted once, read back every way the client offers."""

    @classmethod
    def setUpClass(cls):
        cls.client = Client(OPEN.url)
        cls.seen = []
        cls.job_id = cls.client.submit(SMALL_SWEEP)
        cls.final = cls.client.wait(cls.job_id, progress=cls.seen.append, poll_s=0.1, timeout_s=300)

    def test_job_succeeds_with_progress_reported(self):
        self.assertEqual(self.final["status"], "succeeded", self.final)
        self.assertEqual(self.final["id"], self.job_id)
        self.assertEqual(self.final["kind"], "sweep")
        self.assertEqual(self.final["name"], "python client test")
        self.assertGreater(self.final["progress"]["total"], 0)
        self.assertEqual(self.final["progress"]["done"], self.final["progress"]["total"])
        self.assertTrue(self.seen, "the progress callback was never called")
        self.assertIs(self.seen[-1], self.final)
        dones = [job["progress"]["done"] for job in self.seen]
        self.assertEqual(dones, sorted(dones), "progress went backwards")

    def test_status_and_listing(self):
        self.assertEqual(self.client.status(self.job_id)["status"], "succeeded")
        self.assertIn(self.job_id, [job["id"] for job in self.client.jobs(limit=1)])
        self.assertEqual(self.client.health()["status"], "ok")

    def test_points_all_pages(self):
        whole = list(self.client.points(self.job_id, page_size=10000))
        paged = list(self.client.points(self.job_id, page_size=7))
        self.assertEqual(paged, whole)
        grid = {(p["frequency_hz"], p["amplitude_v"]) for p in whole}
        self.assertEqual(len(grid), 20 * 4)
        self.assertEqual(len({p["amplitude_v"] for p in whole}), 4)
        # Every grid point has a stable up-sweep steady state.
        up = [p for p in whole if p["branch"] == "up"]
        self.assertEqual(len(up), 20 * 4)
        for p in whole:
            self.assertIn(p["branch"], ("up", "down", "unstable"))
            for key in ("h_re_n_per_v", "h_im_n_per_v", "peak_force_n", "min_displacement_m", "max_displacement_m"):
                self.assertIn(key, p)

    def test_points_filters(self):
        rows = list(self.client.points(self.job_id, branch="up", amplitude_v=0.6, page_size=6))
        self.assertEqual(len(rows), 20)
        self.assertTrue(all(p["branch"] == "up" and abs(p["amplitude_v"] - 0.6) < 1e-9 for p in rows))
        band = list(self.client.points(self.job_id, branch="up", frequency_min_hz=6, frequency_max_hz=7))
        self.assertTrue(band)
        self.assertTrue(all(6 <= p["frequency_hz"] <= 7 for p in band))
        self.assertEqual(len(band) % 4, 0)  # whole columns: every amplitude of each frequency
        with self.assertRaises(TypeError):
            list(self.client.points(self.job_id, colour="red"))

    def test_points_csv(self):
        text = self.client.points_csv(self.job_id, branch="up")
        lines = text.strip().splitlines()
        self.assertTrue(lines[0].startswith("frequency_hz,amplitude_v,branch"), lines[0])
        self.assertEqual(len(lines), 1 + 20 * 4)
        every = self.client.points_csv(self.job_id).strip().splitlines()
        self.assertEqual(len(every) - 1, len(list(self.client.points(self.job_id))))
        self.assertEqual(len(self.client.points_csv(self.job_id, limit=7).strip().splitlines()), 1 + 7)

    def test_thresholds_and_jumps_csv(self):
        lines = self.client.thresholds_csv(self.job_id).strip().splitlines()
        self.assertEqual(lines[0], "frequency_hz,grazing_amplitude_v,lowest_contact_amplitude_v")
        self.assertEqual(len(lines), 1 + 20)
        jumps = self.client.jumps_csv(self.job_id).strip().splitlines()
        self.assertEqual(jumps[0], "amplitude_v,bistable_from_hz,bistable_to_hz,from_kind,to_kind")
        self.assertEqual(len(jumps) - 1, len(self.client.saturation_map(self.job_id)["jump"]))

    def test_saturation_map(self):
        result = self.client.saturation_map(self.job_id)
        thresholds = result["saturation_threshold"]
        self.assertEqual(len(thresholds), 20)
        frequencies = [t["frequency_hz"] for t in thresholds]
        self.assertEqual(frequencies, sorted(frequencies))
        self.assertAlmostEqual(frequencies[0], 5.0, places=9)
        self.assertAlmostEqual(frequencies[-1], 5 * 1.02 ** 19, places=6)  # paper Eq. 1
        for t in thresholds:
            # At 5 .. 7.3 Hz the paper model grazes between 0.1 and 0.6 V (the map's lower edge).
            self.assertGreater(t["grazing_amplitude_v"], 0.1)
            self.assertLess(t["grazing_amplitude_v"], 0.6)
            self.assertLessEqual(t["lowest_contact_amplitude_v"], t["grazing_amplitude_v"] + 1e-9)
        self.assertIsInstance(result["jump"], list)
        for j in result["jump"]:
            self.assertLess(j["bistable_from_hz"], j["bistable_to_hz"])
        self.assertEqual(result["job"]["id"], self.job_id)
        svg = self.client.saturation_map_svg(self.job_id)
        self.assertIn("<svg", svg)
        self.assertIn("Stroke saturation", svg)

    def test_frf(self):
        frf = self.client.frf(self.job_id, 0.6)
        self.assertAlmostEqual(frf["amplitude_v"], 0.6)
        up = frf["branches"]["up"]
        self.assertEqual(len(up), 20)
        for p in up:
            self.assertAlmostEqual(p["magnitude_n_per_v"], (p["h_re_n_per_v"] ** 2 + p["h_im_n_per_v"] ** 2) ** 0.5, places=12)
        self.assertIn("<svg", self.client.frf_svg(self.job_id, branch="down"))

    def test_cancel_of_a_finished_job_is_409(self):
        with self.assertRaises(StrokelabError) as caught:
            self.client.cancel(self.job_id)
        self.assertEqual(caught.exception.status, 409)
        self.assertEqual(caught.exception.code, "already_finished")

    def test_a_repeated_job_gives_the_same_points(self):
        again = self.client.submit(SMALL_SWEEP)
        self.assertNotEqual(again, self.job_id)
        self.assertEqual(self.client.wait(again, poll_s=0.1, timeout_s=300)["status"], "succeeded")
        strip = lambda rows: [{k: v for k, v in p.items() if k != "job_id"} for p in rows]
        self.assertEqual(strip(self.client.points(again)), strip(self.client.points(self.job_id)))


class ErrorReplies(unittest.TestCase):
    """Error replies arrive as StrokelabError with the server's code, message and field."""

    client = None

    @classmethod
    def setUpClass(cls):
        cls.client = Client(OPEN.url)

    def test_unknown_job_is_404(self):
        for call in (lambda: self.client.status(987654),
                     lambda: list(self.client.points(987654)),
                     lambda: self.client.saturation_map(987654),
                     lambda: self.client.cancel(987654)):
            with self.assertRaises(StrokelabError) as caught:
                call()
            self.assertEqual(caught.exception.status, 404)
            self.assertEqual(caught.exception.code, "unknown_job")
            self.assertIn("987654", caught.exception.message)

    def test_bad_field_names_the_json_pointer(self):
        job = {"kind": "sweep", "model": "paper",
               "grid": {"frequency_hz": {"from": 5, "to": 20, "points": 10},
                        "amplitude_v": {"from": 0.1, "to": -0.6, "points": 3}}}
        with self.assertRaises(StrokelabError) as caught:
            self.client.submit(job)
        e = caught.exception
        self.assertEqual(e.status, 400)
        self.assertEqual(e.code, "invalid_job")
        self.assertEqual(e.field, "/grid/amplitude_v/to")
        self.assertTrue(e.message)
        self.assertIn("/grid/amplitude_v/to", str(e))

    def test_eq1_with_a_last_frequency_is_rejected(self):
        job = {"kind": "sweep", "model": "paper",
               "grid": {"frequency_hz": {"from": 5, "to": 50, "points": 117, "spacing": "eq1"},
                        "amplitude_v": {"from": 0.1, "to": 0.6, "points": 2}}}
        with self.assertRaises(StrokelabError) as caught:
            self.client.submit(job)
        self.assertEqual(caught.exception.field, "/grid/frequency_hz/to")

    def test_unknown_property_and_missing_kind(self):
        with self.assertRaises(StrokelabError) as caught:
            self.client.submit(dict(SMALL_SWEEP, colour="red"))
        self.assertEqual((caught.exception.status, caught.exception.field), (400, "/colour"))
        with self.assertRaises(StrokelabError) as caught:
            self.client.submit({"model": "paper"})
        self.assertEqual((caught.exception.status, caught.exception.field), (400, "/kind"))

    def test_bad_json_body(self):
        with self.assertRaises(StrokelabError) as caught:
            self.client.request("POST", "/v1/jobs", body=b"{not json")
        self.assertEqual(caught.exception.status, 400)
        self.assertEqual(caught.exception.code, "bad_json")

    def test_bad_query_names_the_parameter(self):
        job_id = self.client.submit(SMALL_SWEEP)
        with self.assertRaises(StrokelabError) as caught:
            list(self.client.points(job_id, branch="sideways"))
        self.assertEqual((caught.exception.status, caught.exception.code, caught.exception.field),
                         (400, "bad_query", "branch"))

    def test_unreachable_server(self):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        with self.assertRaises(StrokelabError) as caught:
            Client(f"http://127.0.0.1:{port}", timeout_s=5).status(1)
        self.assertEqual((caught.exception.status, caught.exception.code), (0, "unreachable"))


class Tokens(unittest.TestCase):
    """A server with --token-file and --workers 0: jobs stay queued until cancelled."""

    def test_no_token_is_401(self):
        for token in (None, "not-a-known-token-0123456789"):
            with self.assertRaises(StrokelabError) as caught:
                Client(SECURED.url, token=token or "").status(1)
            self.assertEqual((caught.exception.status, caught.exception.code), (401, "unauthorized"))

    def test_read_token_reads_but_cannot_submit_or_cancel(self):
        submitter = Client(SECURED.url, token=SUBMIT_TOKEN)
        reader = Client(SECURED.url, token=READ_TOKEN)
        job_id = submitter.submit(SMALL_SWEEP)
        self.assertEqual(reader.status(job_id)["status"], "queued")
        with self.assertRaises(StrokelabError) as caught:
            reader.submit(SMALL_SWEEP)
        self.assertEqual((caught.exception.status, caught.exception.code), (403, "forbidden"))
        with self.assertRaises(StrokelabError) as caught:
            reader.cancel(job_id)
        self.assertEqual(caught.exception.status, 403)
        submitter.cancel(job_id)

    def test_cancel_a_queued_job(self):
        client = Client(SECURED.url, token=SUBMIT_TOKEN)
        job_id = client.submit(SMALL_SWEEP)
        self.assertEqual(client.status(job_id)["status"], "queued")  # no workers
        self.assertEqual(client.cancel(job_id)["status"], "cancelled")
        self.assertEqual(client.wait(job_id, timeout_s=5)["status"], "cancelled")
        with self.assertRaises(StrokelabError) as caught:
            client.cancel(job_id)
        self.assertEqual((caught.exception.status, caught.exception.code), (409, "already_finished"))

    def test_token_from_the_environment(self):
        old = os.environ.get("STROKELAB_TOKEN")
        os.environ["STROKELAB_TOKEN"] = READ_TOKEN
        try:
            self.assertEqual(Client(SECURED.url).health()["status"], "ok")
        finally:
            if old is None:
                del os.environ["STROKELAB_TOKEN"]
            else:
                os.environ["STROKELAB_TOKEN"] = old


class ExampleScript(unittest.TestCase):
    def test_example_prints_thresholds_and_jumps(self):
        out = subprocess.run(
            [sys.executable, os.path.join(HERE, "example_sweep.py"), "--server", OPEN.url,
             "--frequency-points", "60", "--amplitude-points", "6"],
            capture_output=True, text=True, timeout=300)
        self.assertEqual(out.returncode, 0, out.stderr)
        self.assertIn("frequency [Hz]", out.stdout)
        self.assertIn("grazing [V]", out.stdout)
        table = [line for line in out.stdout.splitlines() if re.match(r"^\s+\d+\.\d{3}\s+(\d\.\d{4}|-)\s", line)]
        self.assertEqual(len(table), 60)
        # Eq. 1 x 6 amplitudes up to 0.6 V reaches the jump region near 10 .. 15 Hz (paper Fig. 10).
        self.assertIn("Jump (bistable) intervals", out.stdout)
        self.assertIn("succeeded", out.stderr)
        self.assertIn("/?job=", out.stderr)


if __name__ == "__main__":
    unittest.main()
