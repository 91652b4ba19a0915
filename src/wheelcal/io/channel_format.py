"""The channel formats the contract names: one description for the reader and the writer.

A format is a schema's name and encoding and the messages' encoding (as an
MCAP Channel and its Schema record state them), and the schema's text a writer
stores.  Each codec module declares its own (``IMU_FORMAT``,
``ACCEL_BATCH_FORMAT``, ...); the reader recognises channels by
:meth:`ChannelFormat.matches`, the writer writes them from the same record.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from wheelcal.io.mcap_scan import ChannelRecord, SchemaRecord


@dataclass(frozen=True)
class ChannelFormat:
    """How a channel's messages are written: schema name and encoding, message encoding."""

    schema_name: str
    schema_encoding: str
    message_encoding: str
    #: The schema's text, as a writer stores it (empty: wheelcal does not write the format).
    schema_data: bytes = field(default=b"", repr=False)
    #: Other schema names the readers take for this format (ROS 1 and ROS 2 spell types
    #: differently; ``mcap convert`` keeps the one it found).
    also_named: tuple[str, ...] = ()

    def matches(self, channel: ChannelRecord, schema: SchemaRecord | None) -> bool:
        """Whether ``channel`` (with its ``schema``) carries messages of this format."""
        return (
            schema is not None
            and schema.encoding == self.schema_encoding
            and (schema.name == self.schema_name or schema.name in self.also_named)
            and channel.message_encoding == self.message_encoding
        )

    def __str__(self) -> str:
        return f"{self.schema_name} ({self.schema_encoding}/{self.message_encoding})"
