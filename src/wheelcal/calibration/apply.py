"""Write a calibrated copy of a recording: one message out for every message in.

Any recording ``calibrate`` reads goes in (the same reader: MCAP, ROS 1 ``.bag``,
rosbag2 ``.db3`` or folder).  The output is MCAP (``ros2 bag play`` and Foxglove
read it): an MCAP source is copied with every record kept and the calibrated
topic added; any other source gets its accelerometer topic (and gyro) copied as
ROS 2 ``sensor_msgs/msg/Imu`` beside the calibrated one.

Every sample of the topic is corrected — including those the calibration's
reader leaves out (clipped at a rail, a gross outlier, a stray stamp, a repeated
stamp): they are kept, and *flagged* on ``<calibrated topic>/flags`` (one
``wheelcal.SampleFlag`` JSON message per flagged sample: its stamp and the
reason) and counted by reason in the ``wheelcal.apply`` metadata record.  A
clipped sample's corrected value is the rail's, not the force (which was larger).
Only a sample with no value (NaN or inf) has nothing to correct: it is left out,
and counted.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field

import numpy as np

from wheelcal.calibration.gyro_apply import gyro_correction_from, why_no_gyro_correction
from wheelcal.calibration.session_json import load_calibration, load_correction_from
from wheelcal.io import (
    MARK_RECORD,
    ChannelData,
    RawImuSamples,
    accel_channel,
    copy_with_channels,
    flags_channel,
    is_mcap_file,
    read_raw_samples,
    read_recording,
    recording_stamps_ns,
    refuse_existing,
    session_metadata,
    write_channels,
)
from wheelcal.recording import InputPolicy, Recording

CALIBRATION_METADATA_NAME = "wheelcal.calibration"
APPLY_METADATA_NAME = "wheelcal.apply"
#: Why a sample is flagged (the reader's reasons for leaving it out of a calibration).
CLIPPED = "clipped"
REPEATED = "repeated stamp"
CHECKS = "left out by the reader's checks (an outlier, a stray stamp or leading zeros)"
NO_VALUE = "no value (NaN or inf)"
#: A left-out sample this close to a rail the reader found (fraction of the rail) is clipped.
RAIL_BAND = 0.005


@dataclass(frozen=True)
class AppliedCalibration:
    """What ``apply`` wrote: the calibrated topic, the counts in and out, and the flags."""

    topic: str
    flags_topic: str
    messages_in: int
    samples_out: int
    flagged: dict[str, int] = field(default_factory=dict)
    left_out: dict[str, int] = field(default_factory=dict)
    #: What of the source the output carries besides the calibrated topic.
    copied: str = ""
    #: What was done to the gyro: corrected with the sensor's matrix, or why not ("" without one).
    gyro_note: str = ""

    def summary(self) -> str:
        """One line for the command line: counts in = out, or the difference and why."""
        text = f"{self.messages_in} messages in, {self.samples_out} calibrated on {self.topic}"
        if self.flagged:
            parts = ", ".join(f"{n} {why}" for why, n in self.flagged.items())
            text += f"; flagged on {self.flags_topic}: {parts}"
            if CLIPPED in self.flagged:
                text += " (a clipped sample's value is the rail's: the force was larger)"
        if self.left_out:
            parts = ", ".join(f"{n} with {why}" for why, n in self.left_out.items())
            text += f"; not written: {parts}"
        return text + (f"; {self.copied}" if self.copied else "")


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
) -> AppliedCalibration:
    """Write ``destination`` (MCAP): ``source`` with ``<topic>/calibrated`` added.

    The calibration JSON is also stored as an MCAP metadata record named
    ``wheelcal.calibration``.  Each calibrated ``sensor_msgs/msg/Imu`` carries
    the samples' noise covariance M diag(σ²) Mᵀ as its
    ``linear_acceleration_covariance`` (:func:`corrected_covariance`).
    With a gyroscope and a sensor file whose ``gyro`` block has the full matrix and
    bias, the calibrated topic's angular velocity is the corrected rate
    ω = M⁻¹ (g − b − G f) (:mod:`wheelcal.calibration.gyro_apply`); else the gyro is
    not copied into it (``gyro_note`` says which).
    Samples the reader would leave out of a calibration are corrected and flagged
    (module docstring).  A calibration with undetermined parameters needs
    ``allow_partial``.  An existing ``destination`` is refused unless ``replace``
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
    # reader's other checks — damage, units, clock — still refuse bad input).
    policy = InputPolicy(min_duration_s=0.0, min_samples=1, max_clipped_fraction=1.0)
    try:
        recording = read_recording(source, topic=topic, policy=policy)
    except Exception:
        if topic is None:
            raise
        recording = read_recording(source, policy=policy)  # the calibration's topic is absent
    raw = read_raw_samples(source, recording.topic)
    finite = np.all(np.isfinite(raw.accel_mps2), axis=1)
    reasons = flag_reasons(raw, recording)
    stamps, values = raw.time_ns[finite], raw.accel_mps2[finite]
    corrected = correction.apply(values)
    new_topic = out_topic or f"{recording.topic.rstrip('/')}/calibrated"
    flags_topic = f"{new_topic}/flags"
    enc = encoding or ("json" if raw.encoding == "json" else "ros2")
    covariance = corrected_covariance(calibration, correction.matrix)
    raw_gyro = None if raw.gyro_radps is None else raw.gyro_radps[finite]
    gyro, gyro_note, gyro_metadata = _corrected_gyro(calibration, raw_gyro, corrected)
    order = np.argsort(stamps, kind="stable")  # an MCAP writer takes messages in time order
    channel = accel_channel(
        stamps[order],
        corrected[order],
        encoding=enc,
        topic=new_topic,
        batch_size=50,
        accel_covariance_mps2sq=covariance,
        gyro=None if gyro is None else gyro[order],
    )
    flagged = {why: int(np.sum(reasons == why)) for why in (CLIPPED, REPEATED, CHECKS)}
    flagged = {why: n for why, n in flagged.items() if n}
    left_out = {NO_VALUE: int(np.sum(~finite))} if not finite.all() else {}
    marked = finite & (reasons != "")
    channels = [channel]
    if marked.any():
        channels.append(flags_channel(flags_topic, raw.time_ns[marked], reasons[marked]))
    metadata = {
        CALIBRATION_METADATA_NAME: {
            **_calibration_record(calibration, correction, recording.topic, new_topic, covariance),
            **gyro_metadata,
        },
        APPLY_METADATA_NAME: {
            "messages_in": str(raw.time_ns.size),
            "samples_out": str(int(finite.sum())),
            "flagged": json.dumps(flagged),
            "not_written": json.dumps(left_out),
            "flags_topic": flags_topic if marked.any() else "",
        },
    }
    if mark is not None:
        metadata[MARK_RECORD] = dict(mark)
    copied = _write(raw, recording, destination, channels, metadata, replace)
    return AppliedCalibration(
        topic=new_topic,
        flags_topic=flags_topic,
        messages_in=int(raw.time_ns.size),
        samples_out=int(finite.sum()),
        flagged=flagged,
        left_out=left_out,
        copied=copied,
        gyro_note=gyro_note,
    )


def _corrected_gyro(calibration: dict, gyro_radps: np.ndarray | None, accel_mps2: np.ndarray):
    """(corrected rates or None, a note for the user, metadata entries) for the gyro."""
    if gyro_radps is None:
        return None, "", {}
    gyro = gyro_correction_from(calibration)
    if gyro is None:
        why = why_no_gyro_correction(calibration)
        return None, f"gyro not corrected (left out of the calibrated topic): {why}", {}
    metadata = {
        "gyro_matrix": json.dumps(gyro.matrix.tolist()),
        "gyro_bias_radps": json.dumps(gyro.bias_radps.tolist()),
        "gyro_equation": "omega = gyro_matrix @ (g - gyro_bias_radps - G @ a)"
        if gyro.g_sensitivity is not None
        else "omega = gyro_matrix @ (g - gyro_bias_radps)",
        **(
            {"gyro_g_sensitivity_radps_per_mps2": json.dumps(gyro.g_sensitivity.tolist())}
            if gyro.g_sensitivity is not None
            else {}
        ),
    }
    return gyro.apply(gyro_radps, accel_mps2), gyro.describe(), metadata


def flag_reasons(raw: RawImuSamples, recording: Recording) -> np.ndarray:
    """Per raw sample, why the checked reader would leave it out ("" where it keeps it).

    A stamp the reader kept is kept (its first copy; later copies of the same stamp
    are ``repeated stamp``); a sample it left out is ``clipped`` when an axis sits
    at a rail the reader found, else left out by its other checks.
    """
    reasons = np.full(raw.time_ns.size, "", dtype=object)
    finite = np.all(np.isfinite(raw.accel_mps2), axis=1)
    kept = np.isin(raw.time_ns, recording_stamps_ns(recording))
    order = np.argsort(raw.time_ns, kind="stable")
    repeated = np.zeros(raw.time_ns.size, dtype=bool)
    repeated[order[1:]] = np.diff(raw.time_ns[order]) == 0
    reasons[kept & repeated & finite] = REPEATED
    gone = ~kept & finite
    reasons[gone] = CHECKS
    rails = recording.clip_limits_mps2
    if rails is not None and gone.any():
        at_rail = np.zeros(raw.time_ns.size, dtype=bool)
        for k in range(3):
            for side, rail in enumerate(rails[k]):
                if not np.isfinite(rail):
                    continue
                band = RAIL_BAND * abs(rail)
                v = raw.accel_mps2[:, k]
                at_rail |= (v <= rail + band) if side == 0 else (v >= rail - band)
        reasons[gone & at_rail] = CLIPPED
    return reasons


def _calibration_record(calibration, correction, source_topic, new_topic, covariance) -> dict:
    """The ``wheelcal.calibration`` metadata record (strings)."""
    return {
        "format": calibration["format"],
        "bias_mps2": json.dumps(list(map(float, correction.bias_mps2))),
        "matrix": json.dumps(np.asarray(correction.matrix).tolist()),
        "equation": "a = matrix @ (v - bias)",
        "source_topic": source_topic,
        "calibrated_topic": new_topic,
        "calibration_json": json.dumps(calibration),
        **(
            {"accel_covariance_mps2sq": json.dumps(covariance.tolist())}
            if covariance is not None
            else {}
        ),
    }


def _write(
    raw: RawImuSamples,
    recording: Recording,
    destination,
    channels: list[ChannelData],
    metadata: dict,
    replace: bool,
) -> str:
    """Copy an MCAP source with the channels added; else a new MCAP with the raw topic too."""
    if is_mcap_file(raw.source):
        copy_with_channels(raw.source, destination, channels, metadata, replace=replace)
        return ""
    order = np.argsort(raw.time_ns, kind="stable")
    original = accel_channel(
        raw.time_ns[order],
        raw.accel_mps2[order],
        encoding="ros2",
        topic=raw.topic,
        gyro=None if raw.gyro_radps is None else raw.gyro_radps[order],
    )
    metadata = {**metadata, "wheelcal.session": session_metadata(recording.info)}
    write_channels(destination, [original, *channels], metadata, profile="ros2", replace=replace)
    return (
        f"the source is a {raw.source_format}: its topic {raw.topic} is copied as ROS 2 "
        "sensor_msgs/msg/Imu (raw values), its other topics are not"
    )


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
