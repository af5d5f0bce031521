"""Every command in the repository's README.md runs as written.

The commands are pulled out of the README's ```sh code blocks (a command continues over lines that
end in a backslash and while a quote is open; `NAME=value` lines are kept as the block's variables)
and its ```python blocks. They run in a scratch directory laid out like the repository root: each
top-level entry of the source tree is linked there (so `regress/jobs`, `clients/python` and
`../shared/data` are found as the README names them), `build/release/strokelab` is the binary under
test, and what the commands write (`var/`, `m.json`, `series.csv`, `backups/`) lands in the scratch
directory. A command passes when it exits with 0 and, if it prints a JSON object, that object has no
"error" member (`curl -s` exits 0 on an HTTP error).

The service's commands (`serve --port 8080 ...`) run with `--port 0` instead, so that a busy port
8080 does not fail the test: each starts, must print its "strokelab serving" line, and is stopped
with SIGINT (Ctrl-C, as the README says) and must exit with 0. Before that, the `tokens` file that
`--token-file tokens` names is written with fresh tokens. The first serve command is then started
again and stays up for the commands after the serve block, in which `127.0.0.1:8080` is replaced
by its port.

Run: python3 -m unittest -v test_readme_commands, with STROKELAB_BINARY and STROKELAB_SOURCE_DIR set
(ctest sets both); STROKELAB_KEEP_SCRATCH=1 keeps the scratch directory.
"""

import json
import os
import re
import secrets
import shlex
import signal
import subprocess
import tempfile
import time
import unittest
from pathlib import Path

SOURCE = Path(os.environ.get("STROKELAB_SOURCE_DIR", Path(__file__).resolve().parents[2]))
BINARY = os.environ.get("STROKELAB_BINARY", str(SOURCE / "build/release/strokelab"))

# Commands that do not run here, and why: (pattern searched in the command, reason). Each must match
# at least one command of the README (a stale entry fails the test).
SKIPPED = [
    (r"^deploy/local\.sh ", "installs packages with apt and builds and tests the whole project: "
                            "this test is one of the tests it runs"),
    (r"tests/bench/engines_bench", "a benchmark: not built by default (STROKELAB_BUILD_BENCHMARKS) "
                                   "and timing is no test"),
    (r"tests/bench/compare_scipy\.py", "a speed study against scipy, minutes long; scipy is not a "
                                       "test dependency"),
    (r"tests/diagnose/fit_zscore_study\.py", "a ~20-minute study, run by hand (ctest "
                                             "fit_zscore_study_few runs 4 of its campaigns)"),
    (r"tests/core/paper_fit_zscore_study\.py", "a study of two binaries, run by hand (ctest "
                                              "paper_fit_zscore_study_few runs 2 of its campaigns)"),
    (r"tests/diagnose/control_study\.py", "a ~10-minute study of 100 campaigns, run by hand (ctest "
                                         "control_study_few runs 2 of them)"),
]
# Commands that need something the test environment may lack: (pattern, path that must exist).
NEEDS = [(r"\.\./shared/data/campaign-a", SOURCE.parent / "shared/data/campaign-a")]

SERVING = re.compile(r"strokelab serving http://[^:]+:(\d+)")
TIMEOUT_S = 600


def code_blocks(text, language):
    """The bodies of the fenced code blocks of one language, in order."""
    return re.findall(r"^```" + language + r"\n(.*?)^```", text, flags=re.S | re.M)


def commands_of(block):
    """(variables, commands) of a shell block: comment lines dropped, continued lines joined."""
    variables, commands, pending = [], [], ""
    for line in block.splitlines():
        if not pending and (not line.strip() or line.lstrip().startswith("#")):
            continue
        pending += line + "\n"
        if pending.rstrip().endswith("\\"):
            continue
        try:
            shlex.split(pending, comments=True)
        except ValueError:  # a quote still open: the command goes on
            continue
        command = pending.strip()
        pending = ""
        if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*=\S+", command):
            variables.append(command)
        else:
            commands.append(command)
    if pending:
        raise AssertionError("unterminated command in README block: " + pending)
    return variables, commands


def reply_error(output):
    """The "error" member of a JSON object printed by a command, if it printed one."""
    text = output.strip()
    if not text.startswith("{"):
        return None
    try:
        reply = json.loads(text)
    except ValueError:
        return None
    return reply.get("error") if isinstance(reply, dict) else None


class ReadmeCommandsTest(unittest.TestCase):
    def setUp(self):
        self.scratch = Path(tempfile.mkdtemp(prefix="strokelab-readme-"))
        self.root = self.scratch / "strokelab"
        self.root.mkdir()
        for entry in SOURCE.iterdir():
            if entry.name not in ("build", "var", ".git"):
                (self.root / entry.name).symlink_to(entry)
        (self.root / "build/release").mkdir(parents=True)
        (self.root / "build/release/strokelab").symlink_to(BINARY)
        if (SOURCE.parent / "shared").exists():
            (self.scratch / "shared").symlink_to(SOURCE.parent / "shared")
        self.server = None
        self.port = None
        self.logs = []

    def tearDown(self):
        self.stop(self.server)
        for log in self.logs:
            log.close()
        if os.environ.get("STROKELAB_KEEP_SCRATCH"):
            print("scratch directory kept:", self.scratch)
        else:
            subprocess.run(["rm", "-rf", str(self.scratch)], check=False)

    def start(self, command, variables):
        """A serve command with --port 0: the process and its port, once it prints where it serves."""
        command = command.replace("--port 8080", "--port 0")
        log = open(self.root / f"serve-{time.monotonic_ns()}.log", "w+")
        self.logs.append(log)
        process = subprocess.Popen(["bash", "-c", "; ".join(variables + ["exec " + command])], cwd=self.root,
                                   stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        while True:
            log.seek(0)
            found = SERVING.search(log.read())
            if found:
                return process, int(found.group(1))
            if process.poll() is not None:
                log.seek(0)
                self.fail(f"`{command}` exited with {process.returncode}:\n{log.read()}")
            time.sleep(0.05)

    def stop(self, process):
        if process is None or process.poll() is not None:
            return
        process.send_signal(signal.SIGINT)
        try:
            self.assertEqual(process.wait(timeout=60), 0, "serve did not exit with 0 on SIGINT")
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
            self.fail("serve did not stop within 60 s of SIGINT")

    def run_command(self, command, variables, language="sh"):
        if self.port is not None:
            command = command.replace("127.0.0.1:8080", f"127.0.0.1:{self.port}")
        argv = ["bash", "-c", "set -e; " + "; ".join(variables + [command])] if language == "sh" else \
               ["/usr/bin/python3", "-c", command]
        done = subprocess.run(argv, cwd=self.root, capture_output=True, text=True, timeout=TIMEOUT_S)
        self.assertEqual(done.returncode, 0, f"`{command}` exited with {done.returncode}:\n{done.stderr[-3000:]}")
        error = reply_error(done.stdout)
        self.assertIsNone(error, f"`{command}` was answered with an error: {error}")

    def test_every_command_runs_as_written(self):
        readme = (SOURCE / "README.md").read_text()
        used = set()
        ran, skipped = [], []
        (self.root / "tokens").write_text(
            f"submit {secrets.token_hex(16)}\nread {secrets.token_hex(16)}\nworker {secrets.token_hex(16)}\n")
        first_serve = None
        for block in code_blocks(readme, "sh"):
            variables, commands = commands_of(block)
            for command in commands:
                skip = next(((pattern, why) for pattern, why in SKIPPED if re.search(pattern, command)), None)
                if skip:
                    used.add(skip[0])
                    skipped.append((command, skip[1]))
                    continue
                missing = [path for pattern, path in NEEDS if re.search(pattern, command) and not path.exists()]
                if missing:
                    skipped.append((command, f"{missing[0]} is not there (it lives beside the repository)"))
                    continue
                ran.append(command)
                with self.subTest(command=command):
                    if re.search(r"strokelab serve\b|\$B serve\b", command):
                        process, _ = self.start(command, variables)
                        self.stop(process)
                        first_serve = first_serve or (command, variables)
                    else:
                        if self.server is None and first_serve is not None:
                            self.server, self.port = self.start(*first_serve)
                        self.run_command(command, variables)
        for block in code_blocks(readme, "python"):
            ran.append("python: " + block.splitlines()[0])
            with self.subTest(python=block[:60]):
                self.run_command(block, [], language="python")
        for pattern, _ in SKIPPED:
            self.assertIn(pattern, used, f"no README command matches the skip rule {pattern!r}: remove it")
        self.assertTrue(any(c.startswith("curl") for c in ran), "the README has no curl command any more")
        print(f"\nran {len(ran)} README commands; skipped {len(skipped)}:")
        for command, why in skipped:
            print(f"  {command.splitlines()[0][:90]}\n      skipped: {why}")


if __name__ == "__main__":
    unittest.main()
