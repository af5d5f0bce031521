"""The deploy files' properties that operators and their engines require (issue 17), checked offline:
the Dockerfile and its build context, the compose file for Debian 12's docker-compose 1.29, and the
Kubernetes manifests against the "restricted" Pod Security Standard, field by field. No engine or
cluster is needed; where docker-compose is installed, `docker-compose config` must accept the file.

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


def k8s_documents():
    return [d for d in yaml.safe_load_all((DEPLOY / "kubernetes" / "strokelab.yaml").read_text()) if d]


def pod_templates():
    """Every pod the manifest makes, by its workload's name (a CronJob's pods through its jobTemplate)."""
    pods = {}
    for d in k8s_documents():
        if d["kind"] in ("Deployment", "StatefulSet", "DaemonSet", "Job"):
            pods[d["metadata"]["name"]] = d["spec"]["template"]["spec"]
        elif d["kind"] == "CronJob":
            pods[d["metadata"]["name"]] = d["spec"]["jobTemplate"]["spec"]["template"]["spec"]
    return pods


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
        self.assertGreater(int(workers.group(1)), 0, "the server keeps an in-process worker")

    def test_workers_take_the_token_from_a_file_and_skip_the_server_healthcheck(self):
        worker = self.compose["services"]["worker"]
        self.assertEqual(worker.get("healthcheck"), {"disable": True})
        self.assertNotIn("--token", " ".join(worker["command"]))
        self.assertIn("/run/secrets/worker_token", " ".join(worker["command"]))


class Kubernetes(unittest.TestCase):
    def test_no_secret_with_tokens_is_shipped(self):
        text = (DEPLOY / "kubernetes" / "strokelab.yaml").read_text()
        self.assertNotIn("CHANGE-ME", text)
        self.assertEqual([d["metadata"]["name"] for d in k8s_documents() if d["kind"] == "Secret"], [])
        self.assertIn("kubectl create secret generic strokelab-tokens", text, "the header says how to create it")

    def test_restricted_pod_security_standard(self):
        templates = pod_templates()
        self.assertEqual(set(templates), {"strokelab", "strokelab-worker", "strokelab-backup"})
        for name, pod in templates.items():
            pod_context = pod.get("securityContext", {})
            for container in pod["containers"] + pod.get("initContainers", []):
                context = container.get("securityContext", {})
                with self.subTest(pod=name, container=container["name"]):
                    self.assertTrue(context.get("runAsNonRoot", pod_context.get("runAsNonRoot")), "runAsNonRoot")
                    self.assertNotEqual(context.get("runAsUser", pod_context.get("runAsUser")), 0)
                    self.assertIs(context.get("allowPrivilegeEscalation"), False, "allowPrivilegeEscalation")
                    self.assertIn("ALL", context.get("capabilities", {}).get("drop", []), "capabilities drop ALL")
                    self.assertEqual(context.get("capabilities", {}).get("add", []), [])
                    self.assertNotIn(context.get("privileged"), (True,))
                    seccomp = context.get("seccompProfile", pod_context.get("seccompProfile", {}))
                    self.assertIn(seccomp.get("type"), ("RuntimeDefault", "Localhost"), "seccompProfile")

    def test_worker_token_is_not_on_the_command_line(self):
        worker = pod_templates()["strokelab-worker"]["containers"][0]
        arguments = " ".join(worker.get("command", []) + worker.get("args", []))
        self.assertNotIn("--token", arguments)
        self.assertNotIn("$(", arguments)
        env = {e["name"]: e for e in worker.get("env", [])}
        self.assertEqual(env["STROKELAB_TOKEN"]["valueFrom"]["secretKeyRef"],
                         {"name": "strokelab-tokens", "key": "worker-token"})

    def test_server_has_a_startup_probe_on_health(self):
        server = pod_templates()["strokelab"]["containers"][0]
        self.assertEqual(server["startupProbe"]["httpGet"]["path"], "/v1/health")
        self.assertIn("livenessProbe", server)

    def test_token_volume_is_readable_by_the_group_only(self):
        pod = pod_templates()["strokelab"]
        secret = next(v["secret"] for v in pod["volumes"] if "secret" in v)
        self.assertEqual(secret.get("defaultMode"), 0o440)
        self.assertEqual(pod["securityContext"]["fsGroup"], 10001)

    def test_volume_warns_that_wal_needs_a_local_filesystem(self):
        text = (DEPLOY / "kubernetes" / "strokelab.yaml").read_text()
        pvc = next(part for part in text.split("\n---\n") if "kind: PersistentVolumeClaim" in part)
        self.assertRegex(pvc, r"WAL[\s\S]*NFS")
        self.assertTrue(re.search(r"WAL[^\n]*\n?[^\n]*NFS", (ROOT / "README.md").read_text()),
                        "README.md does not say that WAL needs a local file system (no NFS)")

    def test_backup_cron_job_copies_the_store_beside_the_server(self):
        cron = next(d for d in k8s_documents() if d["kind"] == "CronJob")
        pod = pod_templates()[cron["metadata"]["name"]]
        command = " ".join(pod["containers"][0]["command"] + pod["containers"][0]["args"])
        self.assertRegex(command, r"strokelab backup --db /var/lib/strokelab/strokelab\.db\s+--to /backups/")
        claims = {v["persistentVolumeClaim"]["claimName"] for v in pod["volumes"] if "persistentVolumeClaim" in v}
        self.assertEqual(claims, {"strokelab-data", "strokelab-backups"})
        # The data volume is ReadWriteOnce: the job must land on the server's node.
        term = pod["affinity"]["podAffinity"]["requiredDuringSchedulingIgnoredDuringExecution"][0]
        self.assertEqual(term["labelSelector"]["matchLabels"]["app.kubernetes.io/component"], "server")
        self.assertEqual(term["topologyKey"], "kubernetes.io/hostname")
        self.assertEqual(cron["spec"]["concurrencyPolicy"], "Forbid")

    def test_metrics_scrape_sends_a_token(self):
        scrape = yaml.safe_load((DEPLOY / "kubernetes" / "prometheus-scrape.yaml").read_text())
        job = next(j for j in scrape["scrape_configs"] if j["job_name"] == "strokelab")
        self.assertEqual(job["metrics_path"], "/metrics")
        self.assertEqual(job["authorization"]["type"], "Bearer")
        self.assertTrue(job["authorization"].get("credentials_file") or job["authorization"].get("credentials"))
        self.assertTrue(job["static_configs"][0]["targets"][0].startswith("strokelab."))


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
