r"""Which reader a recording needs, by its first bytes: MCAP, ROS 1 bag, rosbag2 or CSV.

Every reader gives the same :class:`~wheelcal.io.mcap_scan.McapScan` (schemas,
channels, metadata, per-channel message blocks consumed by sinks), so the
topic choice, the decoders and the sample checks of
:func:`~wheelcal.io.mcap_reader.read_recording` are one path for all:

* ``\x89MCAP0\r\n`` — MCAP (:func:`~wheelcal.io.mcap_scan.scan_mcap`), ROS 2 CDR,
  ROS 1 (``mcap convert``) or wheelcal's JSON messages;
* ``#ROSBAG V2.0`` — a ROS 1 bag (:func:`~wheelcal.io.rosbag1_scan.scan_rosbag1`;
  a bag of another version, e.g. 1.2, is named as such there);
* ``SQLite format 3`` — a rosbag2 ``.db3`` (:func:`~wheelcal.io.rosbag2_scan.scan_rosbag2`),
  as is a rosbag2 folder (``metadata.yaml`` beside its ``.db3`` or ``.mcap``);
* text whose first line is a delimited table — a CSV export, read by
  :func:`~wheelcal.io.csv_recording.read_csv_recording` into a recording
  directly (it is no scan: a CSV has no channels).

:func:`recording_kind` names which, for every reader's dispatch.
"""

from __future__ import annotations

import os
from pathlib import Path

from wheelcal.io.mcap_scan import MAGIC as MCAP_MAGIC
from wheelcal.io.mcap_scan import McapScan, scan_mcap

ROSBAG1_MAGIC = b"#ROSBAG V"  # any version: the ROS 1 reader names one it cannot read
SQLITE_MAGIC = b"SQLite format 3\x00"


def recording_kind(path: str | os.PathLike) -> str:
    """``"mcap"``, ``"rosbag1"``, ``"rosbag2"`` or ``"csv"``, by the first bytes (or a folder).

    Anything else (and what is no regular file) is ``"mcap"``: the MCAP reader
    names what the file is not.
    """
    if Path(path).is_dir() and (Path(path) / "metadata.yaml").is_file():
        return "rosbag2"
    head = _head(path, 4096)
    if head.startswith(ROSBAG1_MAGIC):
        return "rosbag1"
    if head.startswith(SQLITE_MAGIC):
        return "rosbag2"
    if not head.startswith(MCAP_MAGIC):
        from wheelcal.io.csv_recording import looks_like_csv

        if looks_like_csv(head):
            return "csv"
    return "mcap"


def scan_recording(path: str | os.PathLike, sink_for=None) -> McapScan:
    """Scan any supported recording (see the module docstring); errors name the file."""
    if Path(path).is_dir() and (Path(path) / "metadata.yaml").is_file():
        from wheelcal.io.rosbag2_scan import scan_rosbag2

        return scan_rosbag2(path, sink_for)
    head = _head(path)
    if head.startswith(ROSBAG1_MAGIC):
        from wheelcal.io.rosbag1_scan import scan_rosbag1

        return scan_rosbag1(path, sink_for)
    if head.startswith(SQLITE_MAGIC):
        from wheelcal.io.rosbag2_scan import scan_rosbag2

        return scan_rosbag2(path, sink_for)
    # MCAP, and everything else: scan_mcap explains what a file is not.
    return scan_mcap(path, sink_for)


def _head(path: str | os.PathLike, size: int = 16) -> bytes:
    """The first bytes of a regular file (b"" for anything else: scan_mcap names the problem)."""
    try:
        if not Path(path).is_file():
            return b""
        with open(path, "rb") as stream:
            return stream.read(size)
    except OSError:
        return b""
