"""Write a calibrated copy of a recording: every original channel kept, one topic added."""

from __future__ import annotations

import json
import os

import numpy as np

from wheelcal.calibration.session_json import load_calibration, load_correction_from
from wheelcal.io.atomic import refuse_existing
from wheelcal.io.mcap_reader import read_recording
from wheelcal.io.mcap_writer import accel_channel, copy_with_channels, recording_stamps_ns
from wheelcal.io.ownership import MARK_RECORD
from wheelcal.recording.samples import InputPolicy

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
    mark: dict | None = None,
) -> tuple[str, int]:
    """Add ``<topic>/calibrated`` (corrected samples, same stamps) to a copy of ``source``.

    The calibration JSON is also stored as an MCAP metadata record named
    ``wheelcal.calibration``.  Each calibrated ``sensor_msgs/msg/Imu`` carries
    the samples' noise covariance M diag(σ²) Mᵀ as its
    ``linear_acceleration_covariance`` (:func:`corrected_covariance`).
    Returns the new topic and the number of samples.
    Samples the reader repaired or dropped (NaNs, duplicates, clipping) are
    handled as in calibration and listed in the recording's notes.  A
    calibration with undetermined parameters needs ``allow_partial``.  An
    existing ``destination`` is refused unless ``replace``
    (:class:`~wheelcal.io.atomic.OutputExistsError`, before any work and again
    at the atomic install).  ``mark``: the copy's ``wheelcal.output`` record
    (:mod:`wheelcal.io.ownership`; the source's own is not copied).
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
    covariance = corrected_covariance(calibration, correction.matrix)
    channel = accel_channel(
        recording_stamps_ns(recording),
        corrected,
        encoding=enc,
        topic=new_topic,
        batch_size=50,
        accel_covariance_mps2sq=covariance,
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
            **(
                {"accel_covariance_mps2sq": json.dumps(covariance.tolist())}
                if covariance is not None
                else {}
            ),
        }
    }
    if mark is not None:
        metadata[MARK_RECORD] = dict(mark)
    copy_with_channels(source, destination, [channel], metadata, replace=replace)
    return new_topic, recording.samples


def raw_noise_std_mps2(calibration: dict) -> np.ndarray | None:
    """The raw samples' noise σ per axis: the rests' floor, else the fit's noise (None if neither).

    ``fit.noise_floor_mps2`` is measured on the rests, independent of the
    model; ``fit.noise_std_mps2`` is the marginal σ of the fit's noise model
    (a sensor's pooled file has only this one).
    """
    fit = calibration.get("fit", {})
    for key in ("noise_floor_mps2", "noise_std_mps2"):
        values = fit.get(key)
        if values is not None and all(isinstance(v, int | float) for v in values):
            sigma = np.asarray(values, dtype=float)
            if np.all(np.isfinite(sigma)) and np.all(sigma > 0):
                return sigma
    return None


def corrected_covariance(calibration: dict, matrix) -> np.ndarray | None:
    """Noise covariance of a = M (v − b): M diag(σ²) Mᵀ, (m/s²)² (None: σ unknown).

    Only the sample noise: the calibration's own σ is common to every sample
    (a systematic error of this sensor), not noise a filter may average.
    """
    sigma = raw_noise_std_mps2(calibration)
    if sigma is None:
        return None
    m = np.asarray(matrix, dtype=float)
    return m @ np.diag(sigma**2) @ m.T
