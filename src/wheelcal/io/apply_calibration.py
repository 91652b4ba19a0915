"""Write a calibrated copy of a recording: every original channel kept, one topic added."""

from __future__ import annotations

import json
import os

import numpy as np

from wheelcal.io.atomic import refuse_existing
from wheelcal.io.calibration_json import load_calibration, load_correction_from
from wheelcal.io.mcap_reader import read_recording
from wheelcal.io.mcap_writer import accel_channel, copy_with_channels, recording_stamps_ns
from wheelcal.io.sample_checks import InputPolicy

CALIBRATION_METADATA_NAME = "wheelcal.calibration"


def apply_calibration(
    calibration_path: str | os.PathLike,
    source: str | os.PathLike,
    destination: str | os.PathLike,
    topic: str | None = None,
    out_topic: str | None = None,
    encoding: str | None = None,
    allow_partial: bool = False,
    replace: bool = False,
) -> tuple[str, int]:
    """Add ``<topic>/calibrated`` (corrected samples, same stamps) to a copy of ``source``.

    The calibration JSON is also stored as an MCAP metadata record named
    ``wheelcal.calibration``.  Returns the new topic and the number of samples.
    Samples the reader repaired or dropped (NaNs, duplicates, clipping) are
    handled as in calibration and listed in the recording's notes.  A
    calibration with undetermined parameters needs ``allow_partial``.  An
    existing ``destination`` is refused unless ``replace``
    (:class:`~wheelcal.io.atomic.OutputExistsError`, before any work and again
    at the atomic install).
    """
    if not replace:
        refuse_existing(destination)
    calibration = load_calibration(calibration_path, allow_partial=allow_partial)
    correction = load_correction_from(calibration)
    topic = topic or calibration.get("source", {}).get("topic") or None
    # Applying needs no spin: any readable recording, however short, is corrected (the
    # reader's other checks — damage, units, NaNs, clock — still refuse bad input).
    policy = InputPolicy(min_duration_s=0.0, min_samples=1)
    try:
        recording = read_recording(source, topic=topic, policy=policy)
    except Exception:
        if topic is None:
            raise
        recording = read_recording(source, policy=policy)  # the calibration's topic is absent
    corrected = correction.apply(recording.accel_mps2)
    new_topic = out_topic or f"{recording.topic.rstrip('/')}/calibrated"
    enc = encoding or ("json" if "wheelcal" in recording.topic else "ros2")
    channel = accel_channel(
        recording_stamps_ns(recording), corrected, encoding=enc, topic=new_topic, batch_size=50
    )
    metadata = {
        CALIBRATION_METADATA_NAME: {
            "format": calibration["format"],
            "bias_mps2": json.dumps(list(map(float, correction.bias_mps2))),
            "matrix": json.dumps(np.asarray(correction.matrix).tolist()),
            "equation": "a = matrix @ (v - bias)",
            "source_topic": recording.topic,
            "calibrated_topic": new_topic,
            "calibration_json": json.dumps(calibration),
        }
    }
    copy_with_channels(source, destination, [channel], metadata, replace=replace)
    return new_topic, recording.samples
