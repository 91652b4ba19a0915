"""The spine picture in the guide is the code's: re-traced, compared, and no call runs up.

``tools/draw_spine.py`` traces ``wheelcal calibrate`` on a simulated bench recording
(in a fresh interpreter: what is already imported or cached must not change the
picture) and draws the crossings between packages as Mermaid.  The diagram under
"The spine" in ``docs/guide/how-it-works.md`` must be that drawing, the spine must
run from the command line down to the model, and no call may cross a layer upward
or sideways.
"""

from __future__ import annotations

import itertools
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "guide" / "how-it-works.md"
SPINE = ["cli", "calibration", "session", "closedloop", "estimate", "model"]


@pytest.fixture(scope="module")
def traced() -> dict:
    out = subprocess.run(
        [sys.executable, str(REPO / "tools" / "draw_spine.py"), "--json"],
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
    )
    return json.loads(out.stdout)


def _doc_diagram() -> str:
    text = DOC.read_text(encoding="utf-8")
    section = text.split("\n## The spine\n", 1)
    assert len(section) == 2, f'{DOC} has no "## The spine" section'
    found = re.search(r"```mermaid\n(.*?)\n```", section[1], re.S)
    assert found, f'{DOC}: no mermaid diagram under "The spine"'
    return found.group(1)


def test_the_guides_diagram_is_the_codes(traced):
    assert _doc_diagram() == traced["mermaid"], (
        "docs/guide/how-it-works.md's spine differs from the code's: regenerate it with "
        "`python tools/draw_spine.py --mermaid`"
    )


def test_the_spine_runs_down_from_the_command_line_to_the_model(traced):
    assert traced["spine"] == SPINE
    layer = traced["layers"]
    assert all(layer[a] > layer[b] for a, b in itertools.pairwise(SPINE))


def test_no_call_crosses_a_layer_upward_or_sideways(traced):
    wrong = [p for p in traced["pairs"] if p["direction"] != "down"]
    assert traced["up"] == 0 and traced["sideways"] == 0 and not wrong, wrong
    assert traced["down"] > 0
