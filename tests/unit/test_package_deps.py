"""Every package.xml declares what its code imports, and nothing it does not use; the README's
ROS Noetic section installs the same packages.

Imports are read with ``ast`` from each package's Python files (``src/``, ``nodes/``,
``scripts/``; files under ``test/`` are test code) and from the ``#include <...>`` lines of its
C++ files; each imported name is mapped to its rosdep key with the table below. An import the
table does not know fails the test, so a new dependency cannot slip in undeclared.
"""
import ast
import os
import re
import sys
import xml.etree.ElementTree as ET

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
PACKAGES = ("patrolling_sim", "spqrel_nav_lite", "patrol_stage2d")

# Python module (top-level name) -> rosdep key. ROS packages import under their own name.
PYTHON_KEYS = {
    "numpy": "python3-numpy", "scipy": "python3-scipy", "cv2": "python3-opencv",
    "yaml": "python3-yaml", "pandas": "python3-pandas", "matplotlib": "python3-matplotlib",
    "networkx": "python3-networkx", "skimage": "python3-skimage",
    "distributed": "python3-distributed", "dask": "python3-dask",
}
ROS_PYTHON = {"rospy", "rostest", "rosgraph", "roslaunch", "genpy", "actionlib", "tf2_ros",
              "actionlib_msgs", "geometry_msgs", "move_base_msgs", "nav_msgs", "rosgraph_msgs",
              "sensor_msgs", "std_msgs", "std_srvs", "tf2_msgs", "visualization_msgs",
              "patrolling_sim", "spqrel_nav_lite", "patrol_stage2d"}
# C++ include directory -> rosdep key (a header without a directory is the standard library)
CPP_KEYS = {
    "ros": "roscpp", "box2d": "libbox2d-dev", "opencv2": "libopencv-dev",
    "actionlib_msgs": "actionlib_msgs", "move_base_msgs": "move_base_msgs",
    "geometry_msgs": "geometry_msgs", "nav_msgs": "nav_msgs", "rosgraph_msgs": "rosgraph_msgs",
    "sensor_msgs": "sensor_msgs", "std_msgs": "std_msgs", "std_srvs": "std_srvs",
    "tf2_msgs": "tf2_msgs", "sys": None,  # <sys/stat.h>: the C library
}
# PyPI-only modules (no Debian package, so no rosdep key): the requirements file that
# scripts/setup.sh installs into .venv/, and the only subpackage allowed to import them (the
# ROS nodes never do; .importlinter checks that too).
PYPI_ONLY = {"gymnasium": ("scripts/requirements-learning.txt", "patrolling_sim/envs/"),
             "pettingzoo": ("scripts/requirements-learning.txt", "patrolling_sim/envs/")}
# Declared dependencies that no import shows, and why they are needed.
NOT_IMPORTED = {
    "catkin": "build tool",
    "message_generation": "builds patrol_stage2d/SetPose.srv",
    "message_runtime": "runtime of the generated SetPose service",
    "rostest": "runs the package's .test files",
    "python3-torch": "scripts/train_policy.py trains policies (outside the package sources)",
}


def package_xml(pkg):
    """{tag: set of names} of the package's dependency tags."""
    root = ET.parse(os.path.join(ROOT, "src", pkg, "package.xml")).getroot()
    deps = {}
    for el in root:
        if el.tag.endswith("depend"):
            deps.setdefault(el.tag, set()).add(el.text.strip())
    return deps


def is_python(path):
    if path.endswith(".py"):
        return True
    if "." in os.path.basename(path):
        return False
    with open(path, "rb") as f:
        first = f.readline()
    return first.startswith(b"#!") and b"python" in first


def python_files(pkg):
    """(path, is_test) of every Python file of the package but setup.py (catkin's)."""
    base = os.path.join(ROOT, "src", pkg)
    for dirpath, _, files in os.walk(base):
        for f in sorted(files):
            p = os.path.join(dirpath, f)
            if f == "setup.py" or not is_python(p):
                continue
            yield p, os.path.relpath(p, base).split(os.sep)[0] == "test"


def python_imports(path):
    with open(path, encoding="utf-8") as f:
        tree = ast.parse(f.read(), path)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module.split(".")[0]


def used_keys(pkg):
    """{"run": {key: [files]}, "test": ..., "build": ...} from the package's sources."""
    base = os.path.join(ROOT, "src", pkg)
    local = {os.path.splitext(f)[0] for d, _, fs in os.walk(base) for f in fs if f.endswith(".py")}
    used = {"run": {}, "test": {}, "build": {}}
    unknown = []
    for path, is_test in python_files(pkg):
        for mod in python_imports(path):
            if mod in sys.stdlib_module_names or mod in local or mod == pkg:
                continue
            if mod in PYPI_ONLY:
                req, where = PYPI_ONLY[mod]
                if where not in path.replace(os.sep, "/"):
                    unknown.append(f"{os.path.relpath(path, ROOT)}: import {mod} (PyPI only: "
                                   f"allowed under {where} alone)")
                continue
            key = PYTHON_KEYS.get(mod, mod if mod in ROS_PYTHON else None)
            if key is None:
                unknown.append(f"{os.path.relpath(path, ROOT)}: import {mod}")
                continue
            used["test" if is_test else "run"].setdefault(key, []).append(
                os.path.relpath(path, ROOT))
    for dirpath, _, files in os.walk(base):
        for f in sorted(files):
            if not f.endswith((".cpp", ".h", ".hpp")):
                continue
            p = os.path.join(dirpath, f)
            with open(p, encoding="utf-8") as fh:
                for inc in re.findall(r'^\s*#include\s*<([^>/]+)/', fh.read(), re.M):
                    if inc == pkg or (inc in CPP_KEYS and CPP_KEYS[inc] is None):
                        continue
                    if inc not in CPP_KEYS:
                        unknown.append(f"{os.path.relpath(p, ROOT)}: #include <{inc}/...>")
                        continue
                    used["build"].setdefault(CPP_KEYS[inc], []).append(os.path.relpath(p, ROOT))
    return used, unknown


@pytest.mark.parametrize("pkg", PACKAGES)
def test_package_xml_declares_every_import(pkg):
    deps = package_xml(pkg)
    both = deps.get("depend", set())
    run_ok = both | deps.get("exec_depend", set())
    test_ok = run_ok | deps.get("test_depend", set())
    build_ok = both | deps.get("build_depend", set())
    used, unknown = used_keys(pkg)
    assert not unknown, ("imports missing from the table in tests/unit/test_package_deps.py "
                         "(add the rosdep key): " + "; ".join(unknown))
    problems = []
    for kind, ok, tags in (("run", run_ok, "<exec_depend> or <depend>"),
                           ("test", test_ok, "<test_depend>, <exec_depend> or <depend>"),
                           ("build", build_ok, "<depend> or <build_depend>")):
        for key, files in sorted(used[kind].items()):
            if key not in ok and key != pkg:
                problems.append(f"src/{pkg}/package.xml: {key} is not declared as {tags} "
                                f"(imported by {files[0]})")
    declared = set().union(*deps.values())
    imported = set().union(*(set(u) for u in used.values()))
    for key in sorted(declared - imported - set(NOT_IMPORTED)):
        problems.append(f"src/{pkg}/package.xml: {key} is declared but nothing imports it")
    assert not problems, "\n".join(problems)


def test_navigation_stands_alone():
    """spqrel_nav_lite depends on nothing of patrolling_sim (a user may want only the
    navigation)."""
    used, _ = used_keys("spqrel_nav_lite")
    users = {k: v for u in used.values() for k, v in u.items() if k == "patrolling_sim"}
    assert not users, f"spqrel_nav_lite imports patrolling_sim: {users}"
    assert "patrolling_sim" not in set().union(*package_xml("spqrel_nav_lite").values())


def noetic_section():
    with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as f:
        text = f.read()
    m = re.search(r"^## [^\n]*ROS Noetic[^\n]*\n(.*?)(?=^## )", text, re.S | re.M)
    assert m, "README.md has no '## ... ROS Noetic' section"
    return m.group(1)


def test_readme_noetic_section_installs_every_dependency():
    section = noetic_section()
    words = set(re.findall(r"[A-Za-z0-9_.+-]+", section))
    missing = []
    for pkg in PACKAGES:
        for key in sorted(set().union(*package_xml(pkg).values())):
            if key in PACKAGES or key == "catkin":   # the workspace itself; catkin: ros-base
                continue
            apt = (key if key.startswith(("python3-", "lib"))
                   else "ros-noetic-" + key.replace("_", "-"))
            if apt not in words:
                missing.append(f"{apt} (src/{pkg}/package.xml: {key})")
    assert not missing, "README.md ROS Noetic section does not install: " + ", ".join(missing)


def test_pypi_only_modules_are_pinned_in_their_requirements_file():
    """A PyPI-only import is installed by scripts/setup.sh: pinned (==) in its file."""
    for mod, (req, _) in PYPI_ONLY.items():
        with open(os.path.join(ROOT, req), encoding="utf-8") as f:
            pins = re.findall(r"^([A-Za-z0-9_.-]+)==\S+", f.read(), re.M)
        assert mod in pins, f"{req} does not pin {mod}"
    with open(os.path.join(ROOT, "scripts", "setup.sh"), encoding="utf-8") as f:
        setup = f.read()
    assert all(req in setup for req, _ in PYPI_ONLY.values())
