"""The README's two fresh-machine commands stay true (CI runs the second; the first is real)."""

import re
from pathlib import Path

from wheelcal.batch.pipeline import load_pipeline

ROOT = Path(__file__).resolve().parents[1]


def _commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```sh\n(.*?)\n```", text, flags=re.S)
    return [b.strip() for b in blocks[:2]]


def test_readme_opens_with_exactly_two_commands():
    text = (ROOT / "README.md").read_text()
    head = text.split("\n\n", 3)
    assert head[0].startswith("# wheelcal")
    assert head[1].startswith("```sh") and head[2].startswith("```sh")
    assert all("\n" not in c for c in _commands())


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1].strip()
    assert ci == _commands()[1]
    assert "pytest" in ci and "[test]" in ci


def test_main_command_runs_the_bundled_pipeline():
    main_cmd = _commands()[0]
    match = re.search(r"wheelcal batch (\S+\.toml)", main_cmd)
    assert match, main_cmd
    pipeline = load_pipeline(ROOT / match.group(1))
    assert pipeline.simulate is not None and pipeline.simulate.count == 10
    assert pipeline.rerun
