"""Rerun chunks from ready Arrow arrays: the Python-side conversion done once or directly.

Writing a session file, most of the time in Python went to Rerun's own layers
around the Arrow arrays rather than to the data: ``RecordingStream.log(path,
archetype, static=True)`` validates and converts every component of the
archetype, then hands a row to Rerun's batcher (for styles that are the same
in every file); ``rr.TimeColumn`` and ``rr.Scalars.columns`` go through
generic converters and rebuild a list array on every access (≈ 0.1 ms per
chunk, for 15 chunks of samples a file).  Here:

* an archetype's components become one-row columns once
  (:func:`row_columns`, cached by the caller), a static entity one
  :class:`rerun.chunk.Chunk` (:func:`static_chunk`);
* the ``time``, sequence and ``Scalars`` columns of samples are built straight
  from numpy (:func:`duration_index`, :func:`sequence_index`,
  :func:`scalars_column`);
* a ``TensorData`` value (a bar chart's values) is assembled from a template
  (:func:`tensor_f64`; Rerun's converter takes ≈ 0.2 ms per chart).

The objects handed to ``Chunk.from_columns`` follow its public protocols
(``timeline_name()`` / ``component_descriptor()`` and ``as_arrow_array()``),
and the arrays are the ones Rerun's own helpers build: the same stored rows as
``log(..., static=True)`` and ``send_columns`` (``tests/test_viz_rrd.py``
compares them, array by array and store by store).
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
#: Arrow type of a ``Scalars:scalars`` row (``rr.Scalars.columns``).
_SCALARS_TYPE = pa.list_(pa.float64())


class ArrowBatch:
    """A ready ``pyarrow`` array as a Rerun ``ComponentBatchLike``."""

    def __init__(self, array: pa.Array) -> None:
        self._array = array

    def as_arrow_array(self) -> pa.Array:
        """The array (Rerun's ``ComponentBatchLike`` protocol)."""
        return self._array


class ArrowColumn:
    """A component column (one list per row) whose Arrow array is built already."""

    def __init__(self, descriptor: rr.ComponentDescriptor, array: pa.ListArray) -> None:
        self._descriptor = descriptor
        self._array = array

    def component_descriptor(self) -> rr.ComponentDescriptor:
        """The component (Rerun's ``ComponentColumn`` protocol)."""
        return self._descriptor

    def as_arrow_array(self) -> pa.ListArray:
        """One list of component values per row."""
        return self._array


class ArrowIndex:
    """A timeline column whose Arrow array is built already (Rerun's ``TimeColumnLike``)."""

    def __init__(self, timeline: str, array: pa.Array) -> None:
        self._timeline = timeline
        self._array = array

    def timeline_name(self) -> str:
        """The timeline's name."""
        return self._timeline

    def as_arrow_array(self) -> pa.Array:
        """One time per row."""
        return self._array


def duration_index(timeline: str, time_ns: np.ndarray) -> ArrowIndex:
    """A duration timeline from whole nanoseconds, as ``rr.TimeColumn(duration=...)``."""
    ns = np.ascontiguousarray(time_ns, dtype=np.int64)
    return ArrowIndex(timeline, pa.array(ns.view("timedelta64[ns]"), pa.duration("ns")))


def sequence_index(timeline: str, values: np.ndarray) -> ArrowIndex:
    """A sequence timeline of integers, as ``rr.TimeColumn(sequence=...)``."""
    return ArrowIndex(timeline, pa.array(np.asarray(values, dtype=np.int64), pa.int64()))


@functools.lru_cache(maxsize=32)
def _offsets(rows: int, width: int) -> pa.Array:
    return pa.array(np.arange(0, rows * width + 1, width, dtype=np.int32))


def scalars_column(values: np.ndarray) -> ArrowColumn:
    """``Scalars:scalars`` with one row per line of ``values`` (N, k), as ``rr.Scalars.columns``."""
    v = np.asarray(values, dtype=np.float64)
    rows, width = (v.shape[0], 1) if v.ndim == 1 else v.shape
    flat = pa.array(np.ascontiguousarray(v).reshape(-1))
    array = pa.ListArray.from_arrays(_offsets(rows, width), flat, type=_SCALARS_TYPE)
    return ArrowColumn(rr.Scalars.descriptor_scalars(), array)


def row_columns(*parts) -> tuple[ArrowColumn, ...]:
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
    return tuple(column(d, b.as_arrow_array()) for d, b in batches.items())


def column(descriptor: rr.ComponentDescriptor, array: pa.Array) -> ArrowColumn:
    """A one-row column holding all of ``array`` (a component batch of one row)."""
    offsets = pa.array([0, len(array)], type=pa.int32())
    return ArrowColumn(descriptor, pa.ListArray.from_arrays(offsets, array))


def static_chunk(entity_path: str, columns: Iterable[ArrowColumn]) -> Chunk:
    """A static chunk of one row: what ``log(entity_path, ..., static=True)`` stores."""
    return Chunk.from_columns(entity_path, indexes=[], columns=columns)


@functools.lru_cache(maxsize=8)
def _tensor_template(size: int) -> tuple[pa.StructType, pa.Array, pa.Array, tuple, int]:
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
