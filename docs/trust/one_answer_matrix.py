"""The issue-25 matrix: every recording calibrated right by default, or refused by name.

For each case of ``tests/test_one_answer.py`` (whole sessions on Table II's bench:
an unbalanced wheel at 0.1–0.6 rad/s² on 20°/46°/70° benches with and without a
gyroscope, a warm-up, a nonlinearity, quadratic drag, imbalance + warm-up, three
pushes with an imbalance) one Markdown row: what ``wheelcal.calibrate()`` with
default options did (the effects it added, or its refusal), its worst determined
gain/offset error in σ_CRLB at the truth of the model it fitted, and the same for
the paper's bare model (``model="paper"``).  Confident wrong answers (accepted,
> 5 σ_CRLB, no warning) are counted at the end; the default must have none.

    python docs/trust/one_answer_matrix.py          # ~3 min on two cores
"""

from __future__ import annotations

import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))


def row(case) -> tuple[str, str, str, float | None, bool]:
    from threadpoolctl import threadpool_limits

    import wheelcal
    from loop_truth import sigmas_from_truth
    from test_one_answer import _session
    from wheelcal.recording import CalibrationRefused, RecordingError

    name, gyro = case
    with threadpool_limits(1):
        session = _session(name, gyro)
        out = {}
        for model in ("closed_loop", "paper"):
            try:
                cal = wheelcal.calibrate(session.recording, model=model)
            except (CalibrationRefused, RecordingError) as exc:
                out[model] = (f"refused: `{getattr(exc, 'gate', '') or 'input'}`", None, False)
                continue
            worst = max(abs(v) for v in sigmas_from_truth(session, cal.result).values())
            effects = ", ".join(cal.document["effects"]) or "none"
            out[model] = (effects, worst, bool(cal.document["fit"]["warnings"]))
    label = f"{name}{' + gyro' if gyro else ''}"
    return label, out["closed_loop"], out["paper"]


def _cell(outcome) -> str:
    text, worst, _ = outcome
    return text if worst is None else f"{text} — {worst:.1f}"


def main() -> int:
    from test_one_answer import MATRIX

    print("| recording | default: effects added — worst σ_CRLB | paper's model — worst σ_CRLB |")
    print("|---|---|---|")
    confident_wrong = {"closed_loop": 0, "paper": 0}
    with ProcessPoolExecutor(2) as pool:
        for label, loop, paper in pool.map(row, MATRIX):
            print(f"| {label} | {_cell(loop)} | {_cell(paper)} |")
            for model, (_, worst, warned) in (("closed_loop", loop), ("paper", paper)):
                if worst is not None and worst > 5 and not warned:
                    confident_wrong[model] += 1
    print(
        f"\nconfident wrong answers (accepted, > 5 σ_CRLB, no warning): default "
        f"{confident_wrong['closed_loop']}, paper's model {confident_wrong['paper']}"
    )
    return 1 if confident_wrong["closed_loop"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
