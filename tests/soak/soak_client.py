#!/usr/bin/env python3
"""Soak driver for strokelab serve (called by deploy/soak.sh; standard library only).

Starts `strokelab serve` on loopback with a fresh database, remote `strokelab worker` processes
that are restarted now and then (SIGKILL and SIGTERM in turn), and threads that submit sweeps,
cancel jobs and query (job status, job list, points pages, saturation maps, metrics, health),
until the duration or the request count runs out. Then it checks the database (integrity, each
finished task's rows once) and reports requests, latency percentiles per kind, job outcomes,
points written, errors by kind and the server's memory at the start and the end.
"""
import argparse
import http.client
import json
import os
import random
import shutil
import signal
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter, defaultdict

MAX_OPEN_JOBS = 6          # submitters wait while this many jobs are queued or running
WORKER_RESTART_S = 15.0    # a remote worker is restarted this often [s]
CANCEL_EVERY_S = 2.0       # a canceller acts this often [s]


class Stats:
    """Latencies [ms] by request kind, status codes and errors, shared by all threads."""

    def __init__(self, max_requests):
        self.lock = threading.Lock()
        self.latency_ms = defaultdict(list)
        self.status = Counter()
        self.errors = Counter()
        self.events = Counter()
        self.requests = 0
        self.max_requests = max_requests

    def record(self, kind, ms, status, error=None):
        with self.lock:
            self.requests += 1
            self.latency_ms[kind].append(ms)
            self.status[(kind, status)] += 1
            if error:
                self.errors[error] += 1

    def count(self, event, n=1):
        with self.lock:
            self.events[event] += n

    def exhausted(self):
        with self.lock:
            return self.requests >= self.max_requests


class Api:
    """One keep-alive connection per thread; a failed request reconnects next time."""

    def __init__(self, port, stats):
        self.port, self.stats, self.conn = port, stats, None

    def call(self, kind, method, path, body=None, expect=(200,)):
        start = time.monotonic()
        try:
            if self.conn is None:
                self.conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=30)
            data = json.dumps(body) if body is not None else None
            headers = {"Content-Type": "application/json"} if data else {}
            self.conn.request(method, path, body=data, headers=headers)
            resp = self.conn.getresponse()
            text = resp.read()
        except (OSError, http.client.HTTPException) as e:
            self.conn = None
            self.stats.record(kind, (time.monotonic() - start) * 1e3, "conn", f"{kind}: {type(e).__name__}")
            return None, None
        ms = (time.monotonic() - start) * 1e3
        error = None
        if resp.status not in expect:
            code = ""
            try:
                code = json.loads(text)["error"]["code"]
            except (ValueError, KeyError, TypeError):
                pass
            error = f"{kind}: HTTP {resp.status} {code}".strip()
        self.stats.record(kind, ms, resp.status, error)
        try:
            return resp.status, json.loads(text) if text and resp.getheader("Content-Type", "").startswith("application/json") else text
        except ValueError:
            return resp.status, text


def sweep_job(rng):
    # Random grids of 0.1 to 2 s of work; a few repeat exactly (served from the result cache).
    f = rng.choice([20, 24, 30]) if rng.random() < 0.15 else rng.randint(16, 150)
    return {"kind": "sweep", "model": "paper", "thresholds": rng.random() < 0.5,
            "grid": {"frequency_hz": {"from": 5, "to": 50, "points": f},
                     "amplitude_v": {"from": 0.1, "to": 0.6, "points": rng.randint(1, 8)}}}


class Soak:
    def __init__(self, args):
        self.args = args
        self.stats = Stats(args.max_requests)
        self.stop = threading.Event()
        self.jobs_lock = threading.Lock()
        self.jobs = []             # ids submitted
        self.dir = tempfile.mkdtemp(prefix="strokelab-soak-")
        self.db = os.path.join(self.dir, "soak.db")
        self.server = None
        self.workers = {}          # slot -> Popen
        self.worker_exits = Counter()

    # --- processes -------------------------------------------------------------------------

    def start_server(self):
        log = open(os.path.join(self.dir, "serve.log"), "w")
        self.server = subprocess.Popen(
            [self.args.binary, "serve", "--port", "0", "--db", self.db, "--workers", str(self.args.local_workers),
             "--lease-s", "5", "--quiet"], stdout=log, stderr=log, stdin=subprocess.DEVNULL)
        marker = "strokelab serving http://127.0.0.1:"
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            with open(log.name) as f:
                text = f.read()
            if marker in text:
                return int(text.split(marker, 1)[1].split()[0].rstrip("/").split(":")[0].split("(")[0])
            if self.server.poll() is not None:
                sys.exit(f"soak: the server exited with {self.server.returncode}:\n{text}")
            time.sleep(0.02)
        sys.exit("soak: the server did not come up in 20 s")

    def start_worker(self, slot, generation):
        name = f"soak-w{slot}-g{generation}"
        log = open(os.path.join(self.dir, f"{name}.log"), "w")
        self.workers[slot] = subprocess.Popen(
            [self.args.binary, "worker", "--server", f"http://127.0.0.1:{self.port}", "--name", name, "--threads", "1"],
            stdout=log, stderr=log, stdin=subprocess.DEVNULL)

    def rss_kb(self):
        try:
            with open(f"/proc/{self.server.pid}/status") as f:
                for line in f:
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1])
        except OSError:
            pass
        return -1

    def cleanup(self):
        for p in list(self.workers.values()) + ([self.server] if self.server else []):
            if p.poll() is None:
                p.terminate()
        deadline = time.monotonic() + 20
        for p in list(self.workers.values()) + ([self.server] if self.server else []):
            try:
                p.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()

    # --- threads ---------------------------------------------------------------------------

    def running(self):
        return not self.stop.is_set() and not self.stats.exhausted()

    def submitter(self, seed):
        rng, api = random.Random(seed), Api(self.port, self.stats)
        while self.running():
            status, listing = api.call("list", "GET", "/v1/jobs?limit=50")
            open_jobs = sum(j["status"] in ("queued", "running") for j in listing["jobs"]) if status == 200 else 0
            if open_jobs >= MAX_OPEN_JOBS:
                time.sleep(0.2)
                continue
            status, body = api.call("submit", "POST", "/v1/jobs", sweep_job(rng), expect=(201,))
            if status == 201:
                with self.jobs_lock:
                    self.jobs.append(body["id"])
            time.sleep(rng.uniform(0.05, 0.4))

    def canceller(self, seed):
        rng, api = random.Random(seed), Api(self.port, self.stats)
        while self.running():
            time.sleep(CANCEL_EVERY_S * rng.uniform(0.5, 1.5))
            with self.jobs_lock:
                recent = self.jobs[-8:]
            if recent:
                # 409: it finished first (a race the service must answer cleanly).
                status, _ = api.call("cancel", "DELETE", f"/v1/jobs/{rng.choice(recent)}", expect=(200, 409))
                self.stats.count("cancel 409 (already finished)" if status == 409 else "cancel accepted")

    def querier(self, seed):
        rng, api = random.Random(seed), Api(self.port, self.stats)
        while self.running():
            with self.jobs_lock:
                job = rng.choice(self.jobs) if self.jobs else None
            kind = rng.choice(["status", "points", "saturation-map", "metrics", "health", "list"])
            if job is None or kind == "health":
                api.call("health", "GET", "/v1/health")
            elif kind == "status":
                api.call("status", "GET", f"/v1/jobs/{job}")
            elif kind == "list":
                api.call("list", "GET", "/v1/jobs?limit=20")
            elif kind == "metrics":
                api.call("metrics", "GET", "/metrics")
            elif kind == "points":
                cursor, pages = 0, 0
                while pages < 5 and self.running():
                    status, page = api.call("points", "GET", f"/v1/jobs/{job}/points?limit=200&cursor={cursor}")
                    if status != 200 or page.get("next_cursor") is None:
                        break
                    cursor, pages = page["next_cursor"], pages + 1
            else:
                api.call("saturation-map", "GET", f"/v1/jobs/{job}/saturation-map")
            time.sleep(rng.uniform(0.0, 0.02))

    def worker_keeper(self):
        generation, kill_next = 0, True
        while self.running():
            self.stop.wait(WORKER_RESTART_S / max(1, self.args.workers))
            if not self.running():
                break
            slot = generation % self.args.workers
            generation += 1
            p = self.workers[slot]
            p.send_signal(signal.SIGKILL if kill_next else signal.SIGTERM)
            try:
                code = p.wait(30)
            except subprocess.TimeoutExpired:
                p.kill()
                code = "hung after SIGTERM"
            self.worker_exits[("SIGKILL" if kill_next else "SIGTERM", code)] += 1
            kill_next = not kill_next
            self.start_worker(slot, generation)

    # --- run and report --------------------------------------------------------------------

    def run(self):
        self.port = self.start_server()
        time.sleep(0.3)
        rss_start = self.rss_kb()
        for slot in range(self.args.workers):
            self.start_worker(slot, 0)
        threads = [threading.Thread(target=self.submitter, args=(i,)) for i in range(self.args.submitters)]
        threads += [threading.Thread(target=self.canceller, args=(100 + i,)) for i in range(self.args.cancellers)]
        threads += [threading.Thread(target=self.querier, args=(200 + i,)) for i in range(self.args.queriers)]
        threads.append(threading.Thread(target=self.worker_keeper))
        start = time.monotonic()
        for t in threads:
            t.start()
        rss_peak, rss_by_minute = rss_start, []
        while self.running() and time.monotonic() - start < self.args.duration:
            time.sleep(1)
            rss = self.rss_kb()
            rss_peak = max(rss_peak, rss)
            if time.monotonic() - start >= 60 * (len(rss_by_minute) + 1):
                rss_by_minute.append(rss)  # a leak keeps climbing; caches level off
            if self.server.poll() is not None:
                self.stats.count("server died")
                break
        self.stop.set()
        for t in threads:
            t.join()
        elapsed = time.monotonic() - start
        rss_end = self.rss_kb()
        final = self.drain()
        self.cleanup()
        return self.report(elapsed, {"start": rss_start, "each_minute": rss_by_minute, "peak": rss_peak, "end": rss_end},
                           final)

    def drain(self):
        """Lets the jobs still open finish (workers still running), for a clean count."""
        api = Api(self.port, self.stats)
        deadline = time.monotonic() + self.args.drain_s
        while time.monotonic() < deadline:
            status, body = api.call("list", "GET", "/v1/jobs?limit=500")
            if status == 200 and not any(j["status"] in ("queued", "running") for j in body["jobs"]):
                break
            time.sleep(0.5)
        status, metrics = api.call("metrics", "GET", "/metrics")
        return metrics if isinstance(metrics, (bytes, str)) else b""

    def report(self, elapsed, rss_kb, metrics):
        con = sqlite3.connect(f"file:{self.db}?mode=ro", uri=True)
        jobs = dict(con.execute("SELECT status, count(*) FROM jobs GROUP BY status").fetchall())
        points = con.execute(
            "SELECT coalesce(sum(rows), 0) FROM result_blocks WHERE table_name = 'points'").fetchone()[0]
        # A job's points counter against its stored blocks (a task's rows of a table are one block,
        # stored once: a second completion would fail the block's UNIQUE key).
        bad_jobs = con.execute(
            "SELECT count(*) FROM jobs j WHERE points != (SELECT coalesce(sum(rows), 0) FROM result_blocks r "
            "WHERE r.job_id = j.id AND r.table_name = 'points')").fetchone()[0]
        short_jobs = con.execute(
            "SELECT count(*) FROM jobs j WHERE status = 'succeeded' AND tasks_done != tasks_total").fetchone()[0]
        integrity = con.execute("PRAGMA integrity_check").fetchone()[0]
        con.close()
        if isinstance(metrics, bytes):
            metrics = metrics.decode(errors="replace")
        s = self.stats
        out = {
            "duration_s": round(elapsed, 1),
            "requests": s.requests,
            "requests_per_s": round(s.requests / elapsed, 1),
            "latency_ms": {k: {"n": len(v), "p50": round(pct(v, 50), 2), "p99": round(pct(v, 99), 2),
                               "max": round(max(v), 2)} for k, v in sorted(s.latency_ms.items())},
            "status_codes": {f"{k} {c}": n for (k, c), n in sorted(s.status.items(), key=str)},
            "errors": dict(s.errors),
            "events": dict(s.events),
            "jobs": jobs,
            "points_written": points,
            "result_rows_written_metric": next((l.split()[1] for l in metrics.splitlines()
                                         if l.startswith("strokelab_result_rows_written_total")), None),
            "worker_restarts": {f"{sig} -> exit {code}": n for (sig, code), n in self.worker_exits.items()},
            "server_rss_kb": rss_kb,
            "checks": {"integrity": integrity, "jobs_whose_points_disagree_with_their_rows": bad_jobs,
                       "succeeded_jobs_missing_tasks": short_jobs},
            "dir": self.dir,
        }
        return out


def pct(values, p):
    v = sorted(values)
    return v[min(len(v) - 1, int(round(p / 100 * (len(v) - 1))))]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--binary", required=True)
    ap.add_argument("--duration", type=float, default=300, help="seconds of load (default 300)")
    ap.add_argument("--max-requests", type=int, default=1_000_000, help="stop after this many requests")
    ap.add_argument("--workers", type=int, default=2, help="remote worker processes")
    ap.add_argument("--local-workers", type=int, default=1, help="the server's in-process workers")
    ap.add_argument("--submitters", type=int, default=2)
    ap.add_argument("--cancellers", type=int, default=1)
    ap.add_argument("--queriers", type=int, default=3)
    ap.add_argument("--drain-s", type=float, default=60, help="time left for open jobs to finish at the end")
    ap.add_argument("--json", help="also write the report here")
    ap.add_argument("--keep", action="store_true", help="keep the scratch directory (kept anyway on failure)")
    args = ap.parse_args()
    if args.duration <= 0 or args.max_requests <= 0 or args.workers < 1:
        ap.error("--duration and --max-requests must be positive, --workers at least 1")
    soak = Soak(args)

    def on_signal(signum, frame):
        soak.stop.set()
    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    try:
        out = soak.run()
    finally:
        soak.cleanup()
    text = json.dumps(out, indent=2)
    print(text)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text + "\n")
    ok = (out["checks"]["integrity"] == "ok" and out["checks"]["tasks_with_rows_not_once"] == 0
          and out["checks"]["succeeded_jobs_missing_tasks"] == 0 and "server died" not in out["events"])
    if ok and not args.keep:
        shutil.rmtree(soak.dir, ignore_errors=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
