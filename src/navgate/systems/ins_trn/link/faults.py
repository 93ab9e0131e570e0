"""Fault injection for the link: a seeded filter over the frames one side sends.

Each frame passes through, in order: a drop window (frames sent while ``drop`` is on are lost),
truncation (probability ``truncate``: the frame is cut at a random byte, its delimiter kept so
the receiver resyncs), bit flips (each byte of the frame body flipped in one random bit with
probability ``flip_rate``), duplication (probability ``duplicate``) and reordering (probability
``reorder``: the frame is held back and sent after the next one). Every fault is counted in
``counts``; the same seed gives the same faults.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field


@dataclass
class FaultInjector:
    seed: int = 0
    flip_rate: float = 0.0
    truncate: float = 0.0
    duplicate: float = 0.0
    reorder: float = 0.0
    drop: bool = False
    counts: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("flip_rate", "truncate", "duplicate", "reorder"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} must lie in [0, 1], got {value}")
        self._rng = random.Random(self.seed)
        self._held: bytes | None = None

    def _count(self, name: str, n: int = 1) -> None:
        self.counts[name] = self.counts.get(name, 0) + n

    def __call__(self, frame: bytes) -> list[bytes]:
        """The byte strings to put on the wire for one encoded frame (may be none)."""
        rng = self._rng
        if self.drop:
            self._count("dropped")
            return []
        body = bytearray(frame[:-1])
        if self.truncate and rng.random() < self.truncate:
            del body[rng.randrange(len(body)):]
            self._count("truncated")
        if self.flip_rate:
            flips = 0
            for i in range(len(body)):
                if rng.random() < self.flip_rate:
                    body[i] ^= 1 << rng.randrange(8)
                    flips += 1
            if flips:
                self._count("corrupted_frames")
                self._count("bit_flips", flips)
        out = [bytes(body) + b"\x00"]
        if self.duplicate and rng.random() < self.duplicate:
            out.append(out[0])
            self._count("duplicated")
        if self._held is not None:
            out.append(self._held)
            self._held = None
        elif self.reorder and rng.random() < self.reorder:
            self._held, out = out[0], out[1:]
            self._count("reordered")
        return out
