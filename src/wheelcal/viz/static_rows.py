"""Static Rerun rows as chunks, with the archetype work done once per process.

``RecordingStream.log(path, archetype, static=True)`` validates and converts
every component of the archetype to Arrow, then hands a row to Rerun's
batcher, which turns the rows of each entity into a chunk on another thread.
For the styles of a session file (the same for every file) and its bar charts
(the same abscissa, widths and colour for every file) that work is the same
each time.  Here an archetype's components are converted once into one-row
columns (:func:`row_columns`), a file's static entities become
:class:`rerun.chunk.Chunk` objects (:func:`static_chunk`) and go to the stream
together with the temporal chunks of the same call, in one
``RecordingStream.send_chunks``.

The stored rows are those ``log(..., static=True)`` stores: the same entity,
the same components with the same descriptors and Arrow values, one row per
entity, no timeline.  ``tests/test_viz_rrd.py`` compares the two.

:func:`tensor_f64` builds the Arrow value of a ``TensorData`` component (a bar
chart's values) from a 1-D float64 array directly: Rerun's own converter goes
through Python objects and several Arrow casts (≈ 0.2 ms per chart); the
result is the same array (a test compares them).
"""

from __future__ import annotations

import functools
from collections.abc import Iterable

import numpy as np
import pyarrow as pa
import rerun as rr
from rerun.chunk import Chunk

#: Name of the float64 member of Rerun's ``TensorBuffer`` union.
_F64 = "F64"
#: The one value offset of a one-element dense union.
_ZERO_OFFSET = pa.py_buffer(np.zeros(1, np.int32))


class ArrowBatch:
    """A ready ``pyarrow`` array as a Rerun ``ComponentBatchLike``."""

    def __init__(self, array: pa.Array) -> None:
        self._array = array

    def as_arrow_array(self) -> pa.Array:
        """The array (Rerun's ``ComponentBatchLike`` protocol)."""
        return self._array


def row_columns(*parts) -> tuple[rr.ComponentColumn, ...]:
    """One-row columns of every component of archetypes or component batches.

    Parameters
    ----------
    parts:
        Archetypes (``as_component_batches()``) or iterables of described
        component batches, as ``RecordingStream.log`` takes them.

    Raises
    ------
    ValueError
        If a component comes twice (``log`` would warn and keep the first).
    """
    batches = {}
    for part in parts:
        as_batches = getattr(part, "as_component_batches", None)
        for batch in as_batches() if as_batches is not None else part:
            descriptor = batch.component_descriptor()
            if descriptor in batches:
                raise ValueError(f"component {descriptor} given twice")
            batches[descriptor] = batch
    return tuple(b.partition([len(b.as_arrow_array())]) for b in batches.values())


def column(descriptor: rr.ComponentDescriptor, array: pa.Array) -> rr.ComponentColumn:
    """A one-row column holding all of ``array`` (a component batch of one row)."""
    return rr.ComponentColumn(descriptor, ArrowBatch(array), lengths=[len(array)])


def static_chunk(entity_path: str, columns: Iterable[rr.ComponentColumn]) -> Chunk:
    """A static chunk of one row: what ``log(entity_path, ..., static=True)`` stores."""
    return Chunk.from_columns(entity_path, indexes=[], columns=columns)


@functools.lru_cache(maxsize=8)
def _tensor_template(size: int) -> tuple[pa.StructType, pa.Array, pa.Array, tuple, pa.DataType]:
    """Parts of Rerun's ``TensorData`` value of a 1-D float64 tensor of ``size`` elements."""
    template = rr.components.TensorDataBatch(np.zeros(size)).as_arrow_array()
    union = template.field("buffer")
    names = [field.name for field in union.type]
    f64 = names.index(_F64)
    children = tuple(union.field(k) for k in range(len(names)))
    return template.type, template.field("shape"), template.field("names"), children, f64


def tensor_f64(values: np.ndarray) -> pa.Array:
    """Rerun's ``TensorData`` Arrow value (one element) of a 1-D float64 array.

    The same array as ``rr.components.TensorDataBatch(values).as_arrow_array()``.
    """
    values = np.ascontiguousarray(values, dtype=np.float64).reshape(-1)
    struct_type, shape, names, children, f64 = _tensor_template(values.size)
    union_type = struct_type.field("buffer").type
    children = list(children)
    children[f64] = pa.ListArray.from_arrays(
        pa.array([0, values.size], type=pa.int32()), values, type=union_type.field(f64).type
    )
    # Built on the union type itself: ``UnionArray.from_dense`` would drop its fields'
    # "not null" flags (Rerun's converter casts them back, which costs more).
    buffer = pa.Array.from_buffers(
        union_type,
        1,
        [None, pa.py_buffer(np.array([union_type.type_codes[f64]], np.int8)), _ZERO_OFFSET],
        children=children,
    )
    return pa.StructArray.from_arrays([shape, names, buffer], fields=list(struct_type))
