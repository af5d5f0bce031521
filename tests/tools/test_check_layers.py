"""tools/check_layers.py passes on the tree and fails on each kind of planted wrong-way dependency."""
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
CHECK = os.path.join(ROOT, "tools", "check_layers.py")
LAYERS = ["core", "plot", "data", "report", "jobs", "server", "worker", "cli"]


def run_check(root):
    result = subprocess.run([sys.executable, CHECK, root], capture_output=True, text=True)
    return result.returncode, result.stdout


class LayerCheck(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="layer-check-")
        for layer in LAYERS:
            shutil.copytree(os.path.join(ROOT, layer), os.path.join(self.tmp, layer))

    def tearDown(self):
        shutil.rmtree(self.tmp)

    def append(self, relative, text):
        with open(os.path.join(self.tmp, relative), "a", encoding="utf-8") as f:
            f.write(text)

    def assertFailsNaming(self, *words):
        code, out = run_check(self.tmp)
        self.assertEqual(code, 1, out)
        for word in words:
            self.assertIn(word, out)

    def test_the_tree_passes(self):
        code, out = run_check(ROOT)
        self.assertEqual(code, 0, out)
        self.assertEqual(run_check(self.tmp)[0], 0)

    def test_core_including_the_server(self):
        self.append("core/src/model/model.cc", '\n#include "strokelab/server/store.h"\n')
        self.assertFailsNaming("core/src/model/model.cc", "strokelab/server/store.h")

    def test_a_core_stage_including_a_later_stage(self):
        self.append("core/src/engines/engine.cc", '\n#include "strokelab/diagnose/diagnose.h"\n')
        self.assertFailsNaming("core/src/engines/engine.cc", "core/engines", "core/diagnose")

    def test_the_worker_including_the_http_service(self):
        self.append("worker/src/remote_worker.cc", '\n#include "strokelab/server/service.h"\n')
        self.assertFailsNaming("worker/src/remote_worker.cc")

    def test_a_relative_include_into_another_layer(self):
        self.append("jobs/src/jobs.cc", '\n#include "../../cli/commands.h"\n')
        self.assertFailsNaming("jobs/src/jobs.cc", "cli")

    def test_a_wrong_way_link(self):
        self.append("core/CMakeLists.txt", "\ntarget_link_libraries(strokelab_core PRIVATE strokelab::jobs)\n")
        self.assertFailsNaming("core/CMakeLists.txt", "strokelab::jobs")

    def test_the_worker_linking_the_service(self):
        self.append("worker/CMakeLists.txt", "\ntarget_link_libraries(strokelab_worker PUBLIC strokelab::service)\n")
        self.assertFailsNaming("worker/CMakeLists.txt", "strokelab::service")


if __name__ == "__main__":
    unittest.main()
