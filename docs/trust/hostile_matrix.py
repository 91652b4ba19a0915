"""The hostile-recording matrix of issue 11: every case refused, warned or right.

Prints one Markdown row per case: what wheelcal did (refused with its gate,
accepted with the warnings that name the cause, or accepted silently) and the
worst error of a determined gain/offset in units of the CRLB at the truth.
A *confident wrong answer* (accepted, no warning, > 5 σ_CRLB off, or a value for
an undetermined parameter) is counted at the end; it must be 0.

    python docs/trust/hostile_matrix.py          # ~1 min
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from truth_bound import sigmas_off
from wheelcal.io import read_recording, write_recording
from wheelcal.recording import CalibrationRefused, RecordingError
from wheelcal.session.fit import SessionFit
from wheelcal.simulate import hostile as H
from wheelcal.simulate.gyro import GyroSpec


def rng(seed):
    return np.random.default_rng(seed)


def cases():
    clean = H.clean(rng(2))
    rec = clean.recording
    for factor in (0.1, 1000.0, 1e9, 1.07):
        yield (
            f"radius × {factor:g}",
            clean,
            replace(rec, info=rec.info.merged(radius_m=0.28 * factor)),
        )
    yield "unit: g labelled m/s² (no rests seen)", clean, H.rescaled(clean, 1 / 9.80665, "g")
    yield "unit: m/s² labelled g (no rests seen)", clean, H.rescaled(clean, 9.80665, "m/s2")
    for rate in (1.0, 5.0, 20.0):
        s = H.sampled_at(rng(4), rate)
        yield f"{rate:g} Hz sampling of a 10 rad/s spin", s, s.recording
    for duration in (1800.0, 3600.0):
        s = H.long_spin(rng(5), duration)
        yield f"free spin of {duration / 60:g} min", s, s.recording
    s = H.saturated(rng(6))
    yield "saturated axis, ±1 LSB jitter (via MCAP)", s, _through_file(s.recording)
    for name, builder, seed in (
        ("driven: ω rising smoothly 19.7 → 24.6 rad/s", H.rising, 7),
        ("driven: motor holding speed, ±10 % steps", H.motor_steps, 8),
        ("driven: motor speed wandering ±5 %", H.wandering, 300),
        ("three pushes in one recording", H.three_pushes, 9),
    ):
        s = builder(rng(seed))
        yield name, s, s.recording
    s = H.vibrating(rng(10), 0.5)
    yield "0.5 m/s² broadband vibration", s, s.recording
    s = H.axis_near_wheel_axis(rng(11), 1.0)
    yield "sensor axis 1° from the wheel axis", s, s.recording
    s = H.axis_exactly_radial(rng(12))
    yield "sensor axis exactly radial", s, s.recording
    for gyro, label in ((None, ""), (GyroSpec(), ", with a gyro")):
        s = H.clean(rng(13), gyro=gyro)
        yield (
            f"sample clock 2 % slow (stamps × 0.98){label}",
            s,
            H.clock_scaled(s, 0.98, "slow clock"),
        )


def _through_file(recording):
    import tempfile

    path = Path(tempfile.mkdtemp()) / "case.mcap"
    write_recording(recording, path)
    return read_recording(path)


def main() -> int:
    print("| recording | outcome | worst determined gain/offset (σ_CRLB) |")
    print("|---|---|---:|")
    confident_wrong = 0
    for name, session, recording in cases():
        try:
            result = SessionFit().run(recording)
        except CalibrationRefused as exc:
            print(f"| {name} | refused: `{exc.gate}` | – |")
            continue
        except RecordingError as exc:
            print(f"| {name} | refused: {str(exc)[:60]}… | – |")
            continue
        off = sigmas_off(session, result)
        worst = max(off.values())
        notes = []
        if result.undetermined:
            notes.append("null: " + ", ".join(result.undetermined))
        named = [w for w in result.assessment.warnings if "undetermined" not in w]
        if named:
            shown = next((w for w in named if "radius" in w or "clock" in w), named[0])
            notes.append(f"{len(named)} warning(s), e.g. “{shown[:90]}…”")
        outcome = "accepted" + (" — " + "; ".join(notes) if notes else "")
        if worst > 5 and not named:
            confident_wrong += 1
        print(f"| {name} | {outcome} | {worst:.1f} |")
    print(f"\nconfident wrong answers: {confident_wrong}")
    return 1 if confident_wrong else 0


if __name__ == "__main__":
    raise SystemExit(main())
