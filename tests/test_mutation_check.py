"""The mutation check cannot rot: every deliberate error still applies to today's code.

``tools/mutation_check.py`` replaces exact strings; a refactor that moves the code
would make a mutation test nothing.  Each replacement must match exactly once.
"""

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _mutations():
    spec = importlib.util.spec_from_file_location(
        "mutation_check", ROOT / "tools/mutation_check.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules["mutation_check"] = module
    spec.loader.exec_module(module)
    return module.MUTATIONS


@pytest.mark.parametrize("mutation", _mutations(), ids=lambda m: m.name)
def test_every_mutation_applies_exactly_once(mutation):
    for replacement in mutation.replacements:
        text = (ROOT / replacement.path).read_text(encoding="utf-8")
        assert text.count(replacement.old) == 1, (mutation.name, replacement.path, replacement.old)
        assert replacement.new != replacement.old
