"""Do this tree and a git revision write the same calibrations?  Largest relative difference.

Extracts ``src/wheelcal`` at ``--ref`` as ``wheelcal_ref`` (``bench_versus.py``),
calibrates every recording given with both (``calibrate_session``: the batch's
path, default options) and compares the calibration JSON documents leaf by
leaf: every number by its relative difference |a − b| / max(|a|, |b|), every
other value (a gate, a note, a warning) for equality.  Timings, paths and
provenance are left out.  Prints each recording's largest relative difference
and where it is, the overall maximum, and any non-numeric difference; exits 1
when a difference exceeds ``--tolerance`` (default 1e-9) or a value differs.

Run:  python benchmarks/compare_numbers.py --ref main FILE.mcap ...
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path

#: Keys whose values differ from run to run or between the two trees by design.
IGNORED = {"timings_s", "provenance", "wheelcal_version", "written_utc", "path", "file"}


def _leaves(value, at: str = ""):
    if isinstance(value, dict):
        for key, item in value.items():
            if key not in IGNORED:
                yield from _leaves(item, f"{at}.{key}")
    elif isinstance(value, list):
        for i, item in enumerate(value):
            yield from _leaves(item, f"{at}[{i}]")
    else:
        yield at, value


def _relative(a: float, b: float) -> float:
    if a == b or (math.isnan(a) and math.isnan(b)):
        return 0.0
    return abs(a - b) / max(abs(a), abs(b))


def _document(calibrate, options, path: str, out: Path) -> dict:
    outcome = calibrate(path, options, out, durable=False)
    if outcome.error:
        return {"error": outcome.error.replace(str(out), "<out>")}
    return json.loads(Path(outcome.calibration_path).read_text(encoding="utf-8"))


def compare(now: dict, ref: dict) -> tuple[float, str, list[str], int]:
    """Largest relative difference of the numbers (and where), the other differences, and
    how many numbers were compared."""
    a, b = dict(_leaves(now)), dict(_leaves(ref))
    worst, where, other, count = 0.0, "", [], 0
    for key in sorted(a.keys() | b.keys()):
        x, y = a.get(key, "<missing>"), b.get(key, "<missing>")
        numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (x, y))
        if numbers:
            count += 1
            rel = _relative(float(x), float(y))
            if rel > worst:
                worst, where = rel, key
        elif x != y:
            other.append(f"{key}: {x!r} != {y!r}")
    return worst, where, other, count


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", required=True)
    ap.add_argument("--tolerance", type=float, default=1e-9)
    ap.add_argument("files", nargs="+")
    args = ap.parse_args()
    from bench_versus import extract

    where = Path(tempfile.mkdtemp(prefix="wheelcal-compare-"))
    extract(args.ref, where)
    sys.path.insert(0, str(where))
    from wheelcal_ref.batch.session import calibrate_session as ref_calibrate
    from wheelcal_ref.session.compute import SessionOptions as RefOptions

    from wheelcal.batch.session import calibrate_session
    from wheelcal.session.compute import SessionOptions

    overall, failed = 0.0, False
    for path in args.files:
        now = _document(calibrate_session, SessionOptions(), path, where / "now")
        ref = _document(ref_calibrate, RefOptions(), path, where / "ref")
        worst, at, other, count = compare(now, ref)
        overall = max(overall, worst)
        status = "refused/failed alike" if "error" in now and now == ref else ""
        print(f"{Path(path).name:24s} {count:5d} numbers, max rel diff {worst:.2e}  {at}  {status}")
        for line in other:
            print(f"    differs: {line}")
        failed |= bool(other) or worst > args.tolerance
    print(
        f"{len(args.files)} recordings: max relative difference {overall:.2e} (tolerance {args.tolerance:g})"
    )
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
