"""What a ROS user gets from the package: declared dependencies, installed bags, config, CLI."""

import ast
import configparser
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from ruamel.yaml import YAML

ROOT = Path(__file__).resolve().parents[1]

# Top-level modules of the standard library and of this distribution need no declaration.
OWN = {"tcomp_core", "tcomp_ros"}
# Python modules -> the rosdep key that provides them (None: pip only, said in a comment).
ROSDEP_KEYS = {
    "numpy": "python3-numpy",
    "scipy": "python3-scipy",
    "matplotlib": "python3-matplotlib",
    "ruamel": "python3-ruamel.yaml",
    "yaml": "python3-yaml",
    "rosbags": "python3-rosbags-pip",
    "tqdm": "python3-tqdm",
    "numba": "python3-numba",
    "zstandard": None,
    "lz4": None,
    "distributed": None,
    "pyarrow": None,
}


def imported_top_modules(package: str) -> set[str]:
    modules = set()
    for path in (ROOT / package).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                modules |= {alias.name.split(".")[0] for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                modules.add(node.module.split(".")[0])
    return modules - set(sys.stdlib_module_names) - OWN


def package_xml():
    tree = ET.parse(ROOT / "package.xml")
    depends = {e.text for e in tree.getroot() if e.tag in ("exec_depend", "depend")}
    return depends, (ROOT / "package.xml").read_text()


def test_package_xml_declares_every_ros_package_the_nodes_import():
    depends, _ = package_xml()
    ros = {
        m for m in imported_top_modules("tcomp_ros") if m.endswith("_msgs") or m.startswith("rcl")
    }
    assert {"rclpy", "rosgraph_msgs", "rcl_interfaces", "sensor_msgs"} <= ros
    assert ros <= depends, f"not in package.xml: {sorted(ros - depends)}"


def test_package_xml_declares_the_python_libraries_or_says_they_come_from_pip():
    depends, text = package_xml()
    third_party = imported_top_modules("tcomp_core") | imported_top_modules("tcomp_ros")
    third_party -= {m for m in third_party if m.endswith("_msgs") or m.startswith("rcl")}
    unknown = third_party - set(ROSDEP_KEYS)
    assert not unknown, f"add a rosdep key (or a pip note) for {sorted(unknown)}"
    for module in third_party:
        key = ROSDEP_KEYS[module]
        if key is None:
            assert module in text and "pip" in text, f"package.xml must say {module} is pip-only"
        else:
            assert key in depends, f"{module}: exec_depend {key} missing"


def test_config_applies_under_any_namespace_and_node_name():
    document = YAML(typ="safe").load((ROOT / "config" / "compensator.yaml").read_text())
    assert list(document) == ["/**"]
    assert "window_s" in document["/**"]["ros__parameters"]


def test_console_scripts_land_where_ros2_run_looks():
    config = configparser.ConfigParser()
    config.read(ROOT / "setup.cfg")
    assert config["install"]["install_scripts"] == "$base/lib/tcomp_ros"
    assert config["develop"]["script_dir"] == "$base/lib/tcomp_ros"
    scripts = ast.parse((ROOT / "setup.py").read_text())
    names = {
        node.value.split("=")[0].strip()
        for node in ast.walk(scripts)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and " = " in node.value
    }
    assert {"tcomp", "compensator_node", "replay_node"} <= names


@pytest.mark.slow
def test_installed_bags_are_found_outside_the_checkout(tmp_path):
    # setup.py's data files, installed into a prefix as colcon does, then tcomp_core's lookup run
    # from that prefix's site-packages in another working directory.
    prefix = tmp_path / "install"
    build = tmp_path / "src"
    shutil.copytree(
        ROOT,
        build,
        ignore=shutil.ignore_patterns(
            ".venv", ".git", "out", "build", "*.egg-info", "__pycache__"
        ),
    )
    subprocess.run(
        [sys.executable, "setup.py", "-q", "install_data", "--install-dir", str(prefix)],
        cwd=build,
        check=True,
        capture_output=True,
    )
    share = prefix / "share" / "tcomp_ros"
    bags = sorted(p.name for p in (ROOT / "bags").iterdir() if (p / "metadata.yaml").is_file())
    assert bags
    for bag in bags:
        installed = sorted(p.name for p in (share / "bags" / bag).iterdir())
        assert installed == sorted(p.name for p in (ROOT / "bags" / bag).iterdir())
    assert (share / "config" / "compensator.yaml").is_file()
    site = prefix / "lib" / "python3.12" / "site-packages"
    shutil.copytree(ROOT / "tcomp_core", site / "tcomp_core")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    found = subprocess.run(
        [
            sys.executable,
            "-c",
            "from tcomp_core.bundled import bundled_bag as b; print(b('ramp_500hz'))",
        ],
        cwd=elsewhere,
        env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"},
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    assert Path(found) == share / "bags" / "ramp_500hz"
    assert (Path(found) / "metadata.yaml").is_file()
