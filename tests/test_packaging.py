"""Issue 28, the small things: dependencies as src/ imports them, README and help texts.

* the runtime dependencies are exactly the third-party packages ``src/`` imports
  (optional extras may add more); test-only packages are in the ``test`` extra;
* README names no file outside the project and shows ``study`` with its
  required ``--out``; ``study --help`` is plain text; a radius is in metres.
"""

import ast
import importlib.metadata
import re
import sys
import tomllib
from pathlib import Path

import pytest

from wheelcal.cli.main import main

ROOT = Path(__file__).resolve().parents[1]


def _name(requirement: str) -> str:
    return re.split(r"[\s<>=!~;\[]", requirement, maxsplit=1)[0].lower().replace("_", "-")


def _imported_distributions() -> set[str]:
    modules = set()
    for path in (ROOT / "src" / "wheelcal").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                modules |= {alias.name.split(".")[0] for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                modules.add(node.module.split(".")[0])
    third_party = {m for m in modules if m not in sys.stdlib_module_names and m != "wheelcal"}
    found = importlib.metadata.packages_distributions()
    return {d.lower().replace("_", "-") for m in third_party for d in found.get(m, [m])}


def test_runtime_dependencies_are_what_src_imports():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    runtime = {_name(r) for r in project["dependencies"]}
    extras = project["optional-dependencies"]
    optional = {_name(r) for name in ("dask", "plots") for r in extras[name]}
    imported = _imported_distributions()
    assert imported - runtime - optional == set(), "imported but not declared"
    assert runtime - imported == set(), "declared but never imported by src/"
    test_only = {_name(r) for r in extras["test"]}
    assert {"mcap-ros2-support", "rosbags", "allantools"} <= test_only


def test_readme_points_inside_the_project_and_shows_study_with_out():
    text = (ROOT / "README.md").read_text()
    assert "../shared" not in text
    rows = [line for line in text.splitlines() if line.startswith("| `wheelcal study")]
    assert rows and all("--out" in row for row in rows)


def test_study_help_is_plain_text(capsys):
    with pytest.raises(SystemExit):
        main(["study", "--help"])
    out = capsys.readouterr().out
    assert "``" not in out and ":class:" not in out and "StudyConfig" in out


@pytest.mark.parametrize("command", ["convert", "plan"])
def test_a_radius_is_in_metres_and_280_is_refused(tmp_path, capsys, command):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "distance from the axle in metres" in help_text
    args = (
        ["convert", str(tmp_path / "in.csv"), str(tmp_path / "out.mcap"), "--radius", "280"]
        if command == "convert"
        else ["plan", "--radius", "280"]
    )
    with pytest.raises(SystemExit) as exit_info:
        main(args)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "280 m is not a sensor–axle distance" in err and "0.28 m" in err
    assert not (tmp_path / "out.mcap").exists()
