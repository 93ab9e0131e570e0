"""Frame codec: round trip, resynchronisation after garbage, every corruption rejected and
counted, version mismatch raised."""

from __future__ import annotations

import random
import struct
import zlib

import pytest
from cobs import cobs

from navgate.systems.ins_trn.link import frames


def test_round_trip_split_at_every_byte():
    body = {"t": 12.5, "profile": [0.0, 1.5, -2.25] * 50, "blob": bytes(range(256))}
    wire = frames.encode(3, 65535, body) + frames.encode(4, 1, None)
    assert wire.count(0) == 2  # the only zeros are the two delimiters
    for cut in range(len(wire) + 1):
        dec = frames.Decoder()
        got = dec.feed(wire[:cut]) + dec.feed(wire[cut:])
        assert got == [frames.Frame(3, 65535, body), frames.Frame(4, 1, None)]
        assert dec.bad == {}


def test_garbage_then_resync():
    dec = frames.Decoder()
    got = dec.feed(b"\x07garbage\x00" + frames.encode(1, 2, [1, 2]))
    assert got == [frames.Frame(1, 2, [1, 2])]
    assert sum(dec.bad.values()) == 1


def test_every_single_bit_flip_is_rejected():
    wire = frames.encode(5, 7, {"x": [1.0, 2.0, 3.0]})
    rng = random.Random(0)
    flips = [(i, b) for i in range(len(wire) - 1) for b in range(8)]
    for i, b in rng.sample(flips, 200):
        bad = bytearray(wire)
        bad[i] ^= 1 << b
        dec = frames.Decoder()
        got = dec.feed(bytes(bad) + b"\x00")
        # a flip may split the frame at a new zero; no piece may pass as a good frame
        assert got == [], (i, b)
        assert sum(dec.bad.values()) >= 1


def test_truncated_frame_rejected_and_next_kept():
    wire = frames.encode(1, 1, "hello")
    dec = frames.Decoder()
    got = dec.feed(wire[:5] + b"\x00" + frames.encode(1, 2, "next"))
    assert got == [frames.Frame(1, 2, "next")]
    assert sum(dec.bad.values()) == 1


def test_other_version_raises():
    raw = struct.pack(">BBHI", 9, 1, 0, 1) + b"\xc0"
    wire = cobs.encode(raw + struct.pack(">I", zlib.crc32(raw))) + b"\x00"
    with pytest.raises(frames.VersionMismatch, match="version 9"):
        frames.Decoder().feed(wire)
