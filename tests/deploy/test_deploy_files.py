"""The deploy files' properties that operators and their engines require (issue 17), checked offline:
the Dockerfile and its build context, the compose file for Debian 12's docker-compose 1.29, and the
sbatch file. No engine or cluster is needed; where docker-compose is installed,
`docker-compose config` must accept the compose file.

Run from anywhere: python3 -m unittest -v test_deploy_files (STROKELAB_SOURCE_DIR: the repository,
default two folders up)."""
import os
import pathlib
import re
import shutil
import subprocess
import tempfile
import unittest

import yaml


ROOT = pathlib.Path(os.environ.get("STROKELAB_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
DEPLOY = ROOT / "deploy"


def project_version():
    match = re.search(r"^project\(strokelab VERSION ([0-9.]+)", (ROOT / "CMakeLists.txt").read_text(), re.M)
    assert match, "no project(strokelab VERSION ...) in CMakeLists.txt"
    return match.group(1)


def source_folders():
    """The folders the binary is built from: the top CMakeLists' subdirectories (not tests) and
    the folders the build reads through PROJECT_SOURCE_DIR (schemas, the web page)."""
    top = (ROOT / "CMakeLists.txt").read_text()
    folders = set(re.findall(r"^add_subdirectory\((\w+)\)", top, re.M)) - {"tests"}
    for folder in list(folders):
        for cmake in (ROOT / folder).rglob("CMakeLists.txt"):
            folders.update(re.findall(r"\$\{PROJECT_SOURCE_DIR\}/(\w+)", cmake.read_text()))
    return folders


class DockerImage(unittest.TestCase):
    def setUp(self):
        self.dockerfile = (DEPLOY / "Dockerfile").read_text()

    def test_context_leaves_out_build_and_keeps_the_sources(self):
        ignore = DEPLOY.parent / ".dockerignore"
        self.assertTrue(ignore.exists(), ".dockerignore is missing: build/ goes into the context")
        rules = [line.strip() for line in ignore.read_text().splitlines() if line.strip() and not line.startswith("#")]
        self.assertTrue("*" in rules or "build" in rules or "build/" in rules or "/build" in rules,
                        "build/ is not ignored")
        self.assertNotIn("!build", rules)
        for folder in sorted(source_folders()):
            with self.subTest(folder=folder):
                self.assertRegex(self.dockerfile, rf"(?m)^COPY {folder} {folder}$", "the Dockerfile does not copy it")
                if "*" in rules:
                    self.assertIn("!" + folder, rules, ".dockerignore leaves it out of the context")

    def test_user_and_group_are_10001(self):
        self.assertRegex(self.dockerfile, r"groupadd [^\n]*--gid 10001 strokelab")
        self.assertRegex(self.dockerfile, r"useradd [^\n]*--uid 10001 --gid 10001 ")
        self.assertRegex(self.dockerfile, r"(?m)^USER 10001:10001$")

    def test_healthcheck_asks_the_health_route(self):
        self.assertRegex(self.dockerfile, r"(?m)^HEALTHCHECK .*\n.*/v1/health")

    def test_image_tags_are_the_project_version(self):
        version = project_version()
        files = [DEPLOY / "Dockerfile", DEPLOY / "compose.yaml", DEPLOY / "kubernetes" / "strokelab.yaml",
                 DEPLOY / "README.md", ROOT / "README.md"]
        for path in files:
            for tag in re.findall(r"strokelab:(\d+\.\d+\.\d+)", path.read_text()):
                with self.subTest(file=str(path.relative_to(ROOT))):
                    self.assertEqual(tag, version, "image tag differs from project(VERSION) in CMakeLists.txt")
        self.assertIn("CMakeLists.txt", (DEPLOY / "docker-build.sh").read_text())


class Compose(unittest.TestCase):
    def setUp(self):
        self.text = (DEPLOY / "compose.yaml").read_text()
        self.compose = yaml.safe_load(self.text)

    def test_only_keys_docker_compose_1_29_takes(self):
        # 1.29 refuses a top-level `name` ("'name' does not match any of the regexes").
        self.assertLessEqual(set(self.compose), {"version", "services", "volumes", "secrets", "networks", "configs"})

    def test_docker_compose_config_accepts_it(self):
        compose = shutil.which("docker-compose")
        if not compose:
            self.skipTest("docker-compose is not installed (Debian: apt-get install docker-compose)")
        with tempfile.TemporaryDirectory() as scratch:
            copy = pathlib.Path(scratch) / "compose.yaml"
            copy.write_text(self.text)
            for secret in self.compose.get("secrets", {}).values():
                (pathlib.Path(scratch) / secret["file"]).write_text("")
            result = subprocess.run([compose, "-f", str(copy), "config", "-q"], capture_output=True, text=True)
        self.assertEqual(result.returncode, 0, result.stderr)

    def test_token_files_at_mode_0600_are_owned_by_the_containers_user(self):
        # Compose without swarm mounts a secret's file with the host's owner and mode, so a 0600
        # file must belong to the image's uid; the header says so.
        self.assertRegex(self.text, r"chown 10001:10001 deploy/tokens deploy/worker-token")
        self.assertIn("chmod 0600", self.text)

    def test_fit_and_diagnose_jobs_have_a_worker(self):
        command = " ".join(self.compose["services"]["server"]["command"])
        workers = re.search(r"--workers=\$\{STROKELAB_SERVER_WORKERS:-(\d+)\}", command)
        self.assertTrue(workers, command)
        self.assertGreater(int(workers.group(1)), 0, "fit and diagnose jobs run on in-process workers only")

    def test_workers_take_the_token_from_a_file_and_skip_the_server_healthcheck(self):
        worker = self.compose["services"]["worker"]
        self.assertEqual(worker.get("healthcheck"), {"disable": True})
        self.assertNotIn("--token", " ".join(worker["command"]))
        self.assertIn("/run/secrets/worker_token", " ".join(worker["command"]))


class Slurm(unittest.TestCase):
    def setUp(self):
        self.sbatch = (DEPLOY / "slurm" / "strokelab-workers.sbatch").read_text()

    def test_fits_any_node_and_exits_when_idle(self):
        # A hard-coded --cpus-per-task above a node's CPUs stays pending forever.
        self.assertNotRegex(self.sbatch, r"(?m)^#SBATCH --cpus-per-task")
        self.assertIn("SLURM_CPUS_PER_TASK", self.sbatch)
        self.assertRegex(self.sbatch, r'worker [^\n]*--exit-when-idle "\$exit_when_idle"')


if __name__ == "__main__":
    unittest.main()
