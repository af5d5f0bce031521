#!/usr/bin/env python3
"""Checks that every dependency between strokelab's layers points down (README.md, "Layout").

Two kinds of dependency are read:
  - #include "..." lines in the C++ sources and headers of each layer, and
  - target_link_libraries(...) in each layer's CMakeLists.txt.
A layer may use only the layers listed for it in ALLOWED; inside core, a stage may use only itself
and the stages before it in CORE_STAGES. Tests, clients, tools and deploy scripts are not layers:
they may use anything, and nothing may use them.

Usage: tools/check_layers.py [ROOT]   (ROOT: the repository, default: this script's parent's parent)
Prints one line per violation ("FILE:LINE: ...") and exits 1 when there is any, else prints a
one-line summary and exits 0.
"""
import os
import re
import sys

# Lowest first. Each layer may depend on the layers named here and on nothing else of the project.
ALLOWED = {
    "core": set(),
    "plot": set(),
    "data": {"core"},
    "report": {"core", "plot"},
    "jobs": {"core", "data", "report"},
    "server": {"core", "plot", "data", "report", "jobs"},
    "worker": {"core", "jobs"},
    "cli": {"core", "plot", "data", "report", "jobs", "server", "worker"},
}
# core's stages in dependency order: a stage may include its own headers and those of stages above.
CORE_STAGES = ["base", "signal", "model", "engines", "steady", "sweep", "identify", "diagnose"]
# The CMake targets each layer defines, by the name other targets link them with.
TARGET_LAYER = {
    "strokelab::core": "core", "strokelab_core": "core",
    "strokelab::plot": "plot", "strokelab_plot": "plot",
    "strokelab::data": "data", "strokelab_data": "data",
    "strokelab::report": "report", "strokelab_report": "report",
    "strokelab::jobs": "jobs", "strokelab_jobs": "jobs",
    "strokelab::server": "server", "strokelab_server": "server",
    "strokelab::service": "server", "strokelab_service": "server",
    "strokelab::worker": "worker", "strokelab_worker": "worker",
    "strokelab::regression": "cli", "strokelab_regression": "cli", "strokelab": "cli",
}
SOURCE_SUFFIXES = (".h", ".cc", ".in")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def unit_of(path, root):
    """(layer, stage) of a file of the tree, stage only inside core; (None, None) outside the layers."""
    parts = os.path.relpath(path, root).split(os.sep)
    layer = parts[0]
    if layer not in ALLOWED:
        return None, None
    if layer == "core":
        # core/include/strokelab/STAGE/x.h or core/src/STAGE/x.cc
        stage = parts[3] if parts[1] == "include" and len(parts) > 4 else parts[2] if len(parts) > 3 else None
        return layer, stage
    return layer, None


def included_unit(target, including_file, root):
    """(layer, stage) of an #include target; None when it is not a file of the project."""
    if target.startswith("strokelab/"):
        sub = target.split("/")[1]
        if sub in CORE_STAGES:
            return "core", sub
        if sub in ALLOWED:
            return sub, None
        return "unknown", sub
    resolved = os.path.normpath(os.path.join(os.path.dirname(including_file), target))
    if os.path.exists(resolved):
        return unit_of(resolved, root)
    return None


def may_use(user, used):
    (layer, stage), (used_layer, used_stage) = user, used
    if used_layer == "unknown":
        return False
    if used_layer != layer:
        return used_layer in ALLOWED[layer]
    if layer == "core" and stage in CORE_STAGES and used_stage in CORE_STAGES:
        return CORE_STAGES.index(used_stage) <= CORE_STAGES.index(stage)
    return True


def name(unit):
    layer, stage = unit
    return f"{layer}/{stage}" if stage else layer


def check_includes(root):
    violations, files = [], 0
    for layer in ALLOWED:
        for dirpath, _, filenames in os.walk(os.path.join(root, layer)):
            for filename in sorted(filenames):
                if not filename.endswith(SOURCE_SUFFIXES):
                    continue
                path = os.path.join(dirpath, filename)
                files += 1
                user = unit_of(path, root)
                with open(path, encoding="utf-8", errors="replace") as f:
                    for number, line in enumerate(f, 1):
                        m = INCLUDE.match(line)
                        if not m:
                            continue
                        used = included_unit(m.group(1), path, root)
                        if used and used[0] is not None and not may_use(user, used):
                            violations.append(f"{os.path.relpath(path, root)}:{number}: {name(user)} includes "
                                              f'"{m.group(1)}" of {name(used)}, which it may not depend on')
                        elif used and used[0] is None:
                            violations.append(f"{os.path.relpath(path, root)}:{number}: {name(user)} includes "
                                              f'"{m.group(1)}" from outside the layers')
    return violations, files


def cmake_calls(text, command):
    """(line, arguments) of each call of `command` in a CMake file (comments dropped)."""
    text = re.sub(r"#[^\n]*", "", text)
    for m in re.finditer(r"\b" + command + r"\s*\(([^)]*)\)", text):
        yield text.count("\n", 0, m.start()) + 1, m.group(1).split()


def check_links(root):
    violations, calls = [], 0
    for layer in ALLOWED:
        for dirpath, _, filenames in os.walk(os.path.join(root, layer)):
            if "CMakeLists.txt" not in filenames:
                continue
            path = os.path.join(dirpath, "CMakeLists.txt")
            with open(path, encoding="utf-8") as f:
                text = f.read()
            for line, args in cmake_calls(text, "target_link_libraries"):
                calls += 1
                target = args[0]
                user_layer = TARGET_LAYER.get(target, layer)
                if user_layer != layer:
                    violations.append(f"{os.path.relpath(path, root)}:{line}: {layer} links target {target} of "
                                      f"{user_layer}")
                for dep in args[1:]:
                    used = TARGET_LAYER.get(dep)
                    if used and used != user_layer and used not in ALLOWED[user_layer]:
                        violations.append(f"{os.path.relpath(path, root)}:{line}: {target} ({user_layer}) links "
                                          f"{dep} of {used}, which it may not depend on")
    return violations, calls


def main(argv):
    root = os.path.abspath(argv[1] if len(argv) > 1 else os.path.join(os.path.dirname(__file__), ".."))
    include_violations, files = check_includes(root)
    link_violations, calls = check_links(root)
    violations = include_violations + link_violations
    for v in violations:
        print(v)
    if violations:
        print(f"layer check: {len(violations)} dependencies point the wrong way")
        return 1
    print(f"layer check: {files} files and {calls} target_link_libraries calls, every dependency points down")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
