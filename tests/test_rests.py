"""Rests are where the wheel stands still: never a stretch of samples left out.

A ±4 g sensor clips during the spin of the paper's bench; its clipped samples are
left out, and what remains of a fast stretch had steady block means — it passed for
a rest, whose |a| of 40 m/s² then "differed from g by 96 σ" in a warning blaming the
sensor, and the rests' noise floor and checks were wrong.
"""

from __future__ import annotations

import numpy as np

import wheelcal
from wheelcal.cli.main import main
from wheelcal.estimate.rests import find_rests


def test_a_clipping_sensors_fast_stretch_is_no_rest(tmp_path):
    path = tmp_path / "clipped.mcap"
    assert main(["simulate", str(path), "--seed", "4", "--quantise"]) == 0
    cal = wheelcal.calibrate(path)
    assert "clipped samples" in " ".join(cal.session.recording.notes)
    rests = find_rests(cal.session.recording)
    assert len(rests) >= 2  # before the push and after the stop
    for rest in rests:
        assert abs(np.linalg.norm(rest.mean_mps2) - 9.8) < 0.5, (rest.start_s, rest.mean_mps2)
    assert not [w for w in cal.session.assessment.warnings if "at rest" in w]
