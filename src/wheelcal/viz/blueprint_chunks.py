"""A Rerun blueprint turned into chunks once, then sent into many files.

``RecordingStream.send_blueprint`` rebuilds every blueprint archetype in
Python and logs each one as its own message, every time.  For the session
layout (13 views, ≈ 60 blueprint entities) that was about 10 ms of a 27 ms
file, more than the ≈ 56 000 rows of samples.  Here the layout is converted
once per process into :class:`rerun.chunk.Chunk` objects (one per blueprint
entity, all components of an entity in one chunk, on the ``blueprint``
timeline at 0 as Rerun logs them); a file then gets those chunks plus the
parts that differ between files (the session's time selection), which costs
one message per entity and no Python archetype work.

What the viewer receives is what ``send_blueprint`` sends: a blueprint store
of the file's application id, made active and default.  Two differences, both
invisible in the viewer: every file of a process carries the same view and
container ids (they name views inside one blueprint, never across files), and
the entities carry only the ``blueprint`` timeline, not ``log_time``.

This leans on three internals of the pinned ``rerun-sdk==0.41.0`` (the public
API has no way to send pre-built blueprint chunks): ``Blueprint._log_to_stream``
(here handed a recorder instead of a stream), ``rerun_bindings.new_blueprint``
and ``rerun_bindings.send_blueprint``.  ``tests/test_viz_rrd.py`` reads the
blueprint store back from the file, so a Rerun upgrade that changes them fails
there.
"""

from __future__ import annotations

from collections.abc import Iterable

import rerun as rr
import rerun_bindings
from rerun.chunk import Chunk
from rerun.recording_stream import RecordingStream, get_application_id

from wheelcal.viz.arrow_chunks import ArrowColumn, row_columns, sequence_index

#: The timeline Rerun logs blueprints on (``rerun.blueprint.api``).
BLUEPRINT_TIMELINE = "blueprint"


class _Recorder:
    """Stands in for a RecordingStream: keeps what a blueprint part logs, per entity.

    A blueprint part calls ``stream.log(path, archetype, static=...)``; the
    components of every call on one entity path are merged (a later value of a
    component replaces an earlier one, as a later log would).
    """

    def __init__(self) -> None:
        self.entities: dict[tuple[str, bool], dict] = {}

    def log(self, entity_path: str, entity, *extra, static: bool = False) -> None:
        components = self.entities.setdefault((entity_path, static), {})
        for part in (entity, *extra):
            batches = getattr(part, "as_component_batches", None)
            for batch in batches() if batches is not None else part:
                components[batch.component_descriptor()] = batch

    def rows(self) -> list[tuple[str, bool, tuple[ArrowColumn, ...]]]:
        """(entity path, static, one-row columns) per entity."""
        return [
            (path, static, row_columns(components.values()))
            for (path, static), components in self.entities.items()
        ]


def blueprint_chunk(path: str, static: bool, columns: Iterable[ArrowColumn]) -> Chunk:
    """One blueprint entity's row as a chunk: at 0 on the ``blueprint`` timeline, or static."""
    index = [] if static else [sequence_index(BLUEPRINT_TIMELINE, [0])]
    return Chunk.from_columns(path, indexes=index, columns=columns)


def blueprint_rows(*parts) -> list[tuple[str, bool, tuple[ArrowColumn, ...]]]:
    """(entity path, static, one-row columns) of every entity that blueprint parts log.

    Parameters
    ----------
    parts:
        As for :func:`blueprint_chunks`.
    """
    recorder = _Recorder()
    for part in parts:
        part._log_to_stream(recorder)
    return recorder.rows()


def blueprint_chunks(*parts) -> tuple[Chunk, ...]:
    """The chunks of blueprint parts (a ``Blueprint``, a container, a panel …).

    Parameters
    ----------
    parts:
        Objects with Rerun's ``_log_to_stream(stream)`` — ``rrb.Blueprint``,
        ``rrb.TimePanel`` and the like.

    Returns
    -------
    tuple of rerun.chunk.Chunk
        One chunk per blueprint entity.
    """
    return tuple(blueprint_chunk(*row) for row in blueprint_rows(*parts))


def send_blueprint_chunks(stream: rr.RecordingStream, chunks: Iterable[Chunk]) -> None:
    """Send chunks as the active and default blueprint of ``stream``'s application.

    The equivalent of ``stream.send_blueprint(...)`` for a blueprint already
    in chunks (see :func:`blueprint_chunks`).
    """
    application_id = get_application_id(recording=stream)
    if application_id is None:  # pragma: no cover - a RecordingStream always has one
        raise ValueError("the stream has no application id")
    blueprint_stream = RecordingStream._from_native(
        rerun_bindings.new_blueprint(
            application_id=application_id,
            make_default=False,
            make_thread_default=False,
            default_enabled=True,
        )
    )
    storage = blueprint_stream.memory_recording()
    rr.send_chunks(list(chunks), recording=blueprint_stream)
    rerun_bindings.send_blueprint(
        storage.storage, make_active=True, make_default=True, recording=stream.to_native()
    )
