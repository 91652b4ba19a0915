"""The batch's sensor-level closure: re-read each sensor's free spins and pool their evidence.

Runs :func:`wheelcal.closedloop.sensor_closure.close_sensor` for every
``sensor_id`` with two or more calibrated sessions, using the windows and the
local effects (warm-up, drift, imbalance …) each session's own closed loop found,
and writes the sensor model of the joint fit to ``sensors/<sensor_id>.sensor.json``.
"""

from __future__ import annotations

from collections import defaultdict

from wheelcal.batch.pipeline import Pipeline
from wheelcal.batch.sensors import SENSORS_FOLDER, sensor_file_stem
from wheelcal.calibration import Calibration
from wheelcal.closedloop import ClosureInput, close_sensor
from wheelcal.io import MARK_KEY, atomic_write_text, dumps_indented, json_safe
from wheelcal.model import make_effect


def _inputs(pipeline: Pipeline, members: list[Calibration]) -> list[ClosureInput]:
    from wheelcal.io import read_recording

    options = pipeline.options
    out = []
    for cal in members:
        recording = read_recording(
            cal.source_file,
            topic=cal.document["source"].get("topic") or options.topic,
            info_overrides=options.info_overrides(),
            info_defaults=options.info_defaults(),
            accel_unit=options.accel_unit,
        )
        start, end = cal.window_s
        # A temperature-following offset needs its recording's temperature series, not
        # just its settings: the sensor closure leaves it out (it is session-local anyway).
        # So does a rolling wheel's yaw (the field fit's series, read from its gyro).
        effects = tuple(
            make_effect(name, settings)
            for name, settings in cal.effects.items()
            if name not in ("temperature_offset", "rolling")
        )
        local = tuple(e for e in effects if not e.sensor_intrinsic)
        out.append(ClosureInput(recording.window(start, end), cal.mounting_id, local))
    return out


def run_closure(
    pipeline: Pipeline, calibrations: list[Calibration], stage=None, mark: dict | None = None
) -> dict:
    """``report.json``'s ``closure`` block (and one sensor JSON per sensor)."""
    by_sensor: dict[str, list[Calibration]] = defaultdict(list)
    for cal in calibrations:
        by_sensor[cal.sensor_id].append(cal)
    sensors, skipped = [], []
    for sensor_id, members in sorted(by_sensor.items()):
        if len(members) < 2:
            skipped.append({"sensor_id": sensor_id, "reason": "fewer than two calibrated sessions"})
            continue
        flexible = [
            m for m in members if "spline" in str(m.document.get("motion", {}).get("model", ""))
        ]
        if flexible:
            # Their windows hold pushes, a motor's steps or a brake that only the gyro's
            # flexible wheel angle follows; the closure refits the paper's cubic.
            skipped.append(
                {
                    "sensor_id": sensor_id,
                    "reason": f"{len(flexible)} session(s) fitted with the gyro's flexible wheel "
                    "angle (a driven or pushed wheel): the sensor closure refits the paper's "
                    "cubic, which cannot follow them; the sessions are pooled by their own fits",
                }
            )
            continue
        try:
            closure = close_sensor(
                sensor_id,
                _inputs(pipeline, members),
                alpha=pipeline.options.alpha,
                fit=pipeline.options.fitter(),
            )
        except (ValueError, OSError, ArithmeticError) as exc:
            skipped.append({"sensor_id": sensor_id, "reason": str(exc)})
            continue
        entry = closure.as_dict()
        entry["files"] = [m["source"]["file"] for m in members]
        if closure.sensor_fit is not None:
            stem = sensor_file_stem(sensor_id)
            path = pipeline.output / SENSORS_FOLDER / f"{stem}.sensor.json"
            path.parent.mkdir(parents=True, exist_ok=True)
            doc = {
                "format": "wheelcal.sensor/1",
                "sensor_id": sensor_id,
                **closure.sensor_fit.as_dict(),
                **({MARK_KEY: mark} if mark is not None else {}),
            }
            text = dumps_indented(json_safe(doc)) + "\n"
            if stage is not None:  # with the report set (wheelcal.batch.runner)
                stage.write_text(path, text)
            else:
                atomic_write_text(path, text)
            entry["sensor_file"] = str(path)
        sensors.append(entry)
    return {"sensors": sensors, "skipped": skipped}
