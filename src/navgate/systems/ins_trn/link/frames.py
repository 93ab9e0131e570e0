"""The link's frame codec: COBS-delimited frames (the zero byte is the sync) around a
big-endian header, a msgpack payload and a CRC-32.

Frame on the wire: ``COBS(header | payload | crc32) 0x00``, where

    header = version u8, message type u8, sequence u16, payload length u32   (big-endian, 8 bytes)
    crc32  = zlib.crc32(header | payload), u32 big-endian

COBS (Cheshire and Baker, "Consistent Overhead Byte Stuffing", IEEE/ACM Trans. Networking
7(2), 1999) comes from the ``cobs`` package on PyPI. A frame that fails any check (COBS,
length, CRC, version) is rejected and counted, never raised to the caller: a byte stream
resynchronises at the next zero byte.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field

import msgpack
from cobs import cobs

VERSION = 1
HEADER = struct.Struct(">BBHI")
CRC = struct.Struct(">I")
MAX_PAYLOAD = 1 << 20


class VersionMismatch(Exception):
    """The peer speaks another protocol version (a frame with a good CRC and another version)."""


@dataclass(frozen=True)
class Frame:
    kind: int
    seq: int
    body: object


def encode(kind: int, seq: int, body: object) -> bytes:
    """One frame, COBS-encoded and terminated by the zero byte."""
    payload = msgpack.packb(body, use_bin_type=True)
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes over the {MAX_PAYLOAD} limit")
    raw = HEADER.pack(VERSION, kind & 0xFF, seq & 0xFFFF, len(payload)) + payload
    return cobs.encode(raw + CRC.pack(zlib.crc32(raw))) + b"\x00"


@dataclass
class Decoder:
    """Feeds bytes in, takes whole frames out; bad frames are counted by reason."""

    buffer: bytearray = field(default_factory=bytearray)
    bad: dict[str, int] = field(default_factory=dict)
    good: int = 0

    def _reject(self, reason: str) -> None:
        self.bad[reason] = self.bad.get(reason, 0) + 1

    def feed(self, data: bytes) -> list[Frame]:
        self.buffer += data
        frames: list[Frame] = []
        while (end := self.buffer.find(0)) >= 0:
            chunk = bytes(self.buffer[:end])
            del self.buffer[: end + 1]
            if chunk:
                frame = self._decode(chunk)
                if frame is not None:
                    frames.append(frame)
        if len(self.buffer) > 2 * MAX_PAYLOAD:  # no sync for too long: drop what we hold
            self._reject("overlong")
            self.buffer.clear()
        return frames

    def _decode(self, chunk: bytes) -> Frame | None:
        try:
            raw = cobs.decode(chunk)
        except cobs.DecodeError:
            self._reject("cobs")
            return None
        if len(raw) < HEADER.size + CRC.size:
            self._reject("short")
            return None
        body, (crc,) = raw[:-CRC.size], CRC.unpack(raw[-CRC.size:])
        if zlib.crc32(body) != crc:
            self._reject("crc")
            return None
        version, kind, seq, length = HEADER.unpack_from(body)
        if length != len(body) - HEADER.size:
            self._reject("length")
            return None
        if version != VERSION:
            raise VersionMismatch(f"peer speaks link version {version}, this side {VERSION}")
        try:
            payload = msgpack.unpackb(body[HEADER.size:], raw=False)
        except Exception:  # msgpack raises several types for malformed data
            self._reject("payload")
            return None
        self.good += 1
        return Frame(kind, seq, payload)
