#!/usr/bin/python3
"""Times one points-only sweep two ways, with one or more strokelab binaries taken in turn.

  cli      `strokelab sweep ... --no-thresholds --threads T` (summary only): wall time of the process;
  service  `strokelab serve --workers T` on a fresh database, the same grid submitted as a job
           (thresholds false): the job's finished_ms - created_ms, from submission to its last row
           stored (the server's clock; polled every 50 ms, which does not change it).

The ratio service / cli is what the store and the service add to the computation. Give --binary
several times (e.g. the code before a change, built in another worktree, and after) and the runs
alternate binary by binary within each round, so that a busy machine slows them alike:

  tests/bench/service_vs_cli.py --binary /work/old/build/release/strokelab --binary build/release/strokelab --rounds 3

Not a ctest test: timings are not pass/fail. Prints one line per run, then the medians per binary.
"""
import argparse
import json
import os
import re
import shutil
import signal
import statistics
import subprocess
import tempfile
import time
import urllib.request


def cli_seconds(binary, args):
    cmd = [binary, "sweep", "--frequency-hz", "5:50", "--frequency-points", str(args.frequency_points),
           "--amplitude-v", "0.1:0.6", "--amplitude-points", str(args.amplitude_points),
           "--no-thresholds", "--threads", str(args.threads)]
    start = time.monotonic()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.monotonic() - start


def request(url, body=None):
    data = json.dumps(body).encode() if body is not None else None
    req = urllib.request.Request(url, data=data, headers={"Content-Type": "application/json"} if data else {})
    with urllib.request.urlopen(req, timeout=60) as r:
        return json.loads(r.read())


def service_seconds(binary, args):
    scratch = tempfile.mkdtemp(prefix="strokelab-service-vs-cli-")
    log_path = os.path.join(scratch, "serve.log")
    with open(log_path, "w") as log:
        server = subprocess.Popen([binary, "serve", "--port", "0", "--workers", str(args.threads), "--db",
                                   os.path.join(scratch, "jobs.db"), "--quiet"], stderr=log, stdout=log)
    try:
        port = None
        deadline = time.monotonic() + 30
        while port is None:
            if time.monotonic() > deadline or server.poll() is not None:
                raise RuntimeError("the server did not come up: " + open(log_path).read())
            m = re.search(r"strokelab serving http://127\.0\.0\.1:(\d+)", open(log_path).read())
            port = int(m.group(1)) if m else None
            time.sleep(0.01)
        base = "http://127.0.0.1:%d" % port
        job = {"kind": "sweep", "model": "paper", "thresholds": False,
               "grid": {"frequency_hz": {"from": 5, "to": 50, "points": args.frequency_points},
                        "amplitude_v": {"from": 0.1, "to": 0.6, "points": args.amplitude_points}}}
        job_id = request(base + "/v1/jobs", job)["id"]
        while True:
            status = request("%s/v1/jobs/%d" % (base, job_id))
            if status["status"] not in ("queued", "running"):
                break
            time.sleep(0.05)
        if status["status"] != "succeeded":
            raise RuntimeError("job %s: %s" % (status["status"], status.get("error")))
        return (status["finished_ms"] - status["created_ms"]) / 1000.0
    finally:
        server.send_signal(signal.SIGTERM)
        try:
            server.wait(timeout=30)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
        shutil.rmtree(scratch, ignore_errors=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--binary", action="append", help="a strokelab binary (repeat to compare)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2, help="CLI threads and in-process workers")
    parser.add_argument("--frequency-points", type=int, default=1000)
    parser.add_argument("--amplitude-points", type=int, default=40)
    args = parser.parse_args()
    binaries = args.binary or ["build/release/strokelab"]
    results = {b: {"cli": [], "service": []} for b in binaries}
    print("grid %d x %d, points only, %d threads / in-process workers" %
          (args.frequency_points, args.amplitude_points, args.threads))
    for r in range(args.rounds):
        for b in binaries:
            cli = cli_seconds(b, args)
            service = service_seconds(b, args)
            results[b]["cli"].append(cli)
            results[b]["service"].append(service)
            print("round %d  %-50s cli %6.3f s  service %6.3f s  ratio %5.2f" % (r + 1, b, cli, service, service / cli),
                  flush=True)
    for b in binaries:
        cli, service = statistics.median(results[b]["cli"]), statistics.median(results[b]["service"])
        ratios = [s / c for s, c in zip(results[b]["service"], results[b]["cli"])]
        print("median   %-50s cli %6.3f s  service %6.3f s  ratio %5.2f (per round %s)" %
              (b, cli, service, service / cli, ", ".join("%.2f" % x for x in ratios)))


if __name__ == "__main__":
    main()
