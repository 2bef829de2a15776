"""The protobuf wire format, as much as ONNX files need: read a message's fields, write them back.

For the few edits this package makes to an ONNX model in memory (``onnx_detector._free_image_dims``,
``stereo_classic.matching.learned``), without the ``onnx`` package: importing it costs half a second (its
``ml_dtypes``), a start-up a camera pipeline should not pay for a few fields.
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["Field", "pb_fields", "pb_encode", "pb_strings"]

Field = tuple[int, int, bytes]  # protobuf field: number, wire type, payload (a length-delimited one without its length)


def _varint(buf: bytes, i: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        if i >= len(buf):
            raise ValueError("truncated protobuf varint")
        byte = buf[i]
        i += 1
        value |= (byte & 0x7F) << shift
        if byte < 0x80:
            return value, i
        shift += 7
        if shift > 63:
            raise ValueError("protobuf varint longer than 10 bytes")


def pb_fields(buf: bytes) -> list[Field]:
    """The fields of one protobuf message, in order (wire types 0, 1, 2 and 5; groups are not used by ONNX)."""
    out: list[Field] = []
    i, n = 0, len(buf)
    while i < n:
        key, i = _varint(buf, i)
        num, wire = key >> 3, key & 7
        start = i
        if wire == 0:
            _, i = _varint(buf, i)
        elif wire == 1:
            i += 8
        elif wire == 5:
            i += 4
        elif wire == 2:
            length, start = _varint(buf, i)
            i = start + length
        else:
            raise ValueError(f"protobuf wire type {wire} (field {num}) is not ONNX's")
        if i > n:
            raise ValueError(f"truncated protobuf field {num}")
        out.append((num, wire, buf[start:i]))
    return out


def pb_encode(fields: Iterable[Field]) -> bytes:
    """One protobuf message from its fields (``pb_fields``'s inverse: ``pb_encode(pb_fields(b)) == b``)."""

    def varint(value: int) -> bytes:
        out = bytearray()
        while True:
            byte = value & 0x7F
            value >>= 7
            if value:
                out.append(byte | 0x80)
            else:
                out.append(byte)
                return bytes(out)

    parts = []
    for num, wire, raw in fields:
        parts.append(varint(num << 3 | wire))
        if wire == 2:
            parts.append(varint(len(raw)))
        parts.append(raw)
    return b"".join(parts)


def pb_strings(fields: Iterable[Field], number: int) -> list[str]:
    """The string fields ``number`` of a message, in order (e.g. a ``NodeProto``'s inputs: 1)."""
    return [raw.decode("utf-8", "replace") for num, wire, raw in fields if num == number and wire == 2]
