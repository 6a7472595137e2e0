#!/usr/bin/python3
"""Checks the package layering of DESIGN.md: nothing points upwards.

For each package under src/: its package.xml may depend only on the ROPES packages below it,
every `#include <ropes_X/...>` must name itself or a declared dependency, and `colcon graph`
must show exactly the DAG of the design card (ropes_msgs edges are optional: streaming).

Usage: layering_test.py WORKSPACE          check the workspace
       layering_test.py --self-test WORKSPACE   check that violations are caught
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

# who may depend on whom (DESIGN.md, "Packages and who may include whom")
ALLOWED = {
    "ropes_core": set(),
    "ropes_msgs": {"ropes_core"},
    "ropes_nn": {"ropes_core"},
    "ropes_sim": {"ropes_core", "ropes_msgs"},
    "ropes_crl": {"ropes_core", "ropes_nn", "ropes_msgs"},
    "ropes_eval": {"ropes_core", "ropes_crl", "ropes_sim", "ropes_nn", "ropes_msgs"},
}
# edges the design requires (ropes_sim renders and writes datasets: it needs no autodiff, so
# no edge to ropes_nn)
REQUIRED = {("ropes_msgs", "ropes_core"), ("ropes_nn", "ropes_core"), ("ropes_sim", "ropes_core"),
            ("ropes_crl", "ropes_core"), ("ropes_crl", "ropes_nn"), ("ropes_eval", "ropes_core"),
            ("ropes_eval", "ropes_crl"), ("ropes_eval", "ropes_sim"), ("ropes_eval", "ropes_nn")}
DEP_TAGS = ("depend", "build_depend", "build_export_depend", "exec_depend", "test_depend")
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"](ropes_[a-z]+)/', re.M)
SOURCE_EXT = (".hpp", ".h", ".cpp", ".cc", ".cxx", ".in")


def declared_deps(package_dir):
    root = ET.parse(os.path.join(package_dir, "package.xml")).getroot()
    return {e.text.strip() for tag in DEP_TAGS for e in root.iter(tag)
            if e.text and e.text.strip().startswith("ropes_")}


def check(workspace, use_colcon=True):
    problems = []
    src = os.path.join(workspace, "src")
    packages = sorted(d for d in os.listdir(src) if os.path.isfile(os.path.join(src, d, "package.xml")))
    if set(packages) != set(ALLOWED):
        problems.append(f"packages under src/ are {packages}; the design has {sorted(ALLOWED)}")
    edges = set()
    for pkg in packages:
        pkg_dir = os.path.join(src, pkg)
        deps = declared_deps(pkg_dir)
        edges |= {(pkg, d) for d in deps}
        for d in sorted(deps - ALLOWED.get(pkg, set())):
            problems.append(f"{pkg}/package.xml depends on {d}, which is not below {pkg}")
        for dirpath, _, files in os.walk(pkg_dir):
            for name in files:
                if not name.endswith(SOURCE_EXT):
                    continue
                path = os.path.join(dirpath, name)
                with open(path, encoding="utf-8", errors="replace") as f:
                    for used in INCLUDE.findall(f.read()):
                        if used != pkg and used not in deps:
                            rel = os.path.relpath(path, workspace)
                            problems.append(f"{rel} includes a header of {used}, "
                                            f"which {pkg} does not depend on")
                        if used != pkg and used not in ALLOWED.get(pkg, set()):
                            rel = os.path.relpath(path, workspace)
                            problems.append(f"{rel} includes a header of {used}, above {pkg}")
    for a, b in sorted(REQUIRED - edges):
        problems.append(f"{a}/package.xml lacks the design's dependency on {b}")
    if use_colcon:
        out = subprocess.run(["/usr/bin/colcon", "graph", "--dot"], cwd=workspace, check=True,
                             capture_output=True, text=True).stdout
        graph = set(re.findall(r'"(ropes_\w+)" -> "(ropes_\w+)"', out))
        # colcon lists test dependencies too; the layering rule covers them the same way
        if graph != edges:
            problems.append(f"colcon graph shows {sorted(graph)}, package.xml files say {sorted(edges)}")
        print("colcon graph edges:", ", ".join(f"{a} -> {b}" for a, b in sorted(graph)))
    return problems


def self_test(workspace):
    """Copies the package.xml files and one bad header into a scratch tree: must fail."""
    scratch = tempfile.mkdtemp()
    try:
        for pkg in ALLOWED:
            os.makedirs(os.path.join(scratch, "src", pkg, "include", pkg))
            shutil.copy(os.path.join(workspace, "src", pkg, "package.xml"),
                        os.path.join(scratch, "src", pkg, "package.xml"))
        if check(scratch, use_colcon=False):
            print("self-test: the copied package.xml files already fail")
            return 1
        with open(os.path.join(scratch, "src", "ropes_nn", "include", "ropes_nn", "x.hpp"), "w") as f:
            f.write("#include <ropes_sim/truncated_normal.hpp>\n")
        found = check(scratch, use_colcon=False)
        if not any("ropes_nn/include/ropes_nn/x.hpp includes a header of ropes_sim" in p for p in found):
            print("self-test: an upward include went unnoticed:", found)
            return 1
        print("self-test: caught", found[0])
        return 0
    finally:
        shutil.rmtree(scratch)


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--self-test":
        return self_test(sys.argv[2])
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    problems = check(sys.argv[1])
    for p in problems:
        print("LAYERING:", p)
    print("layering:", "FAIL" if problems else "OK")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
