"""``wheelcal.SampleFlag``: one JSON message per flagged sample, beside a calibrated topic.

``wheelcal apply`` corrects every sample, including those a calibration leaves out
(clipped at a rail, an outlier, a repeated stamp); each of those gets a message
``{"timestamp_ns": int, "reason": str}`` on ``<calibrated topic>/flags``, logged at
its sample's stamp, so a viewer shows the flags on the samples' timeline and a
script finds them by stamp.
"""

from __future__ import annotations

import json

import numpy as np

from wheelcal.io.accel_json import JSON_MESSAGE_ENCODING, JSON_SCHEMA_ENCODING
from wheelcal.io.channel_format import ChannelFormat

SAMPLE_FLAG_SCHEMA_NAME = "wheelcal.SampleFlag"
_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": SAMPLE_FLAG_SCHEMA_NAME,
    "description": "A sample of the calibrated topic that a calibration would leave out",
    "type": "object",
    "properties": {
        "timestamp_ns": {"type": "integer", "description": "the sample's stamp, Unix ns"},
        "reason": {"type": "string", "description": "why it is flagged"},
    },
    "required": ["timestamp_ns", "reason"],
}
SAMPLE_FLAG_FORMAT = ChannelFormat(
    SAMPLE_FLAG_SCHEMA_NAME,
    JSON_SCHEMA_ENCODING,
    JSON_MESSAGE_ENCODING,
    json.dumps(_SCHEMA).encode(),
)


def flags_channel(topic: str, time_ns: np.ndarray, reasons: np.ndarray):
    """The flags of ``time_ns`` (int ns) with their ``reasons``, in time order."""
    from wheelcal.io.mcap_writer import ChannelData

    time_ns = np.asarray(time_ns, dtype=np.int64).reshape(-1)
    order = np.argsort(time_ns, kind="stable")
    messages = tuple(
        (int(t), json.dumps({"timestamp_ns": int(t), "reason": str(r)}).encode())
        for t, r in zip(time_ns[order].tolist(), np.asarray(reasons)[order].tolist(), strict=True)
    )
    return ChannelData.of(SAMPLE_FLAG_FORMAT, topic, messages)
