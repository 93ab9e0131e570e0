"""The block registry: every gateware core that ``navgate build`` and ``navgate report`` know.

A block is a name, a zero-argument factory that returns an Amaranth ``wiring.Component``, and a
one-line description. The factories are named as ``"module:attribute"`` strings and imported
only when a block is built, so that ``navgate build --list`` stays fast and one broken core
cannot hide the others.

The shared cores are listed in :data:`REGISTRY` (one line each). The float32 cores are merged
in from ``navgate.gateware.fp32.BLOCKS`` (a ``name -> class`` dict kept by that package), their
description being the first line of the class docstring. The seed systems' designs are not
known here (``hw`` is a shared library and imports no system): each package that has blocks
publishes a registry of the same shape as :data:`REGISTRY` under the entry-point group
``navgate.blocks`` (pyproject.toml; navgate's own systems publish ``navgate.systems:BLOCKS``),
and :func:`all_blocks` merges every published registry.

Every component built from here documents ``LATENCY`` (cycles from an accepted input to its
result being valid, with the output ready) and ``THROUGHPUT`` (results per cycle at steady
state, e.g. ``1`` for a pipeline, ``1/18`` for an iterative core); both may be class or
instance attributes.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: name -> ("module:attribute" of a zero-argument factory, one-line description)
REGISTRY: dict[str, tuple[str, str]] = {
    "cordic_atan2": (
        "navgate.gateware.cordic:CordicAtan2",
        "CORDIC vectoring atan2 + magnitude, unrolled pipeline (one result per cycle)",
    ),
    "cordic_atan2_iter": (
        "navgate.gateware.cordic:CordicAtan2Iterative",
        "CORDIC vectoring atan2 + magnitude, iterative (one result per ~iterations cycles)",
    ),
    "cordic_sincos": (
        "navgate.gateware.cordic:CordicSinCos",
        "CORDIC rotation mode: cos and sin of a binary angle, pipelined",
    ),
    "goldschmidt_div": (
        "navgate.gateware.goldschmidt:GoldschmidtDivider",
        "Goldschmidt fixed-point divider, pipelined",
    ),
    "goldschmidt_recip": (
        "navgate.gateware.goldschmidt:GoldschmidtReciprocal",
        "Goldschmidt fixed-point reciprocal, pipelined",
    ),
    "fp32_div_iter": (
        "navgate.gateware.fp32:Fp32DivIter",
        "float32 divide, iterative radix-2 (bit-exact to fp32_div; LATENCY 28, one per 27 cycles)",
    ),
    "fp32_sqrt_iter": (
        "navgate.gateware.fp32:Fp32SqrtIter",
        "float32 square root, iterative radix-2 (bit-exact to fp32_sqrt; LATENCY 27, 1/26)",
    ),
    "fixed_mul": (
        "navgate.gateware.fixed:FixedMul",
        "signed Q-format multiplier: full product, truncated/saturated result, overflow flag",
    ),
    # timing yardsticks (navgate.gateware.yardstick): measured in every report's run
    "mul_24x17": (
        "navgate.gateware.yardstick:mul_24x17",
        "yardstick: bare registered unsigned 24x17 multiply (fp32_mul's wider DSP half)",
    ),
    "mul_20x20": (
        "navgate.gateware.yardstick:mul_20x20",
        "yardstick: bare registered signed 20x20 multiply (a Q(20, FRAC) fixed-point product)",
    ),
    "mul_24x24": (
        "navgate.gateware.yardstick:mul_24x24",
        "yardstick: bare registered unsigned 24x24 multiply (whole fp32 significand product)",
    ),
}

#: where the float32 cores keep their own registry (name -> class)
FP32_MODULE = "navgate.gateware.fp32"
#: entry-point group under which packages publish block registries shaped like REGISTRY
ENTRY_POINT_GROUP = "navgate.blocks"


@dataclass(frozen=True)
class Block:
    """One buildable block."""

    name: str
    factory: Callable[[], Any]
    description: str
    #: where the factory lives, ``"module:attribute"`` (the build cache keys a block by it and
    #: caches only blocks whose module is part of navgate, whose sources it fingerprints)
    source: str = ""


def _first_line(doc: str | None) -> str:
    for line in (doc or "").strip().splitlines():
        if line.strip():
            return line.strip().rstrip(".")
    return "(no description)"


def _lazy_factory(target: str) -> Callable[[], Any]:
    module_name, attribute = target.split(":")

    def factory(board: str | None = None) -> Any:
        """The block; for a ``board``, its board variant where the block's class has one
        (a class-level ``for_target(board)``), built instead of the generic block."""
        made = getattr(importlib.import_module(module_name), attribute)
        variant = getattr(made, "for_target", None) if board is not None else None
        return variant(board) if variant is not None else made()

    factory.__qualname__ = factory.__name__ = attribute
    return factory


def _fp32_blocks() -> dict[str, Block]:
    try:
        module = importlib.import_module(FP32_MODULE)
    except ModuleNotFoundError as error:
        # Only the absence of the fp32 package itself is tolerated; a broken import inside
        # it is a real error and propagates.
        if error.name is not None and FP32_MODULE.startswith(error.name):
            return {}
        raise
    return {
        name: Block(name, cls, _first_line(getattr(cls, "__doc__", None)),
                    f"{cls.__module__}:{cls.__qualname__}")
        for name, cls in getattr(module, "BLOCKS", {}).items()
    }


def published_registries() -> dict[str, dict[str, tuple[str, str]]]:
    """The block registries published under :data:`ENTRY_POINT_GROUP`, by entry-point name."""
    from importlib.metadata import entry_points

    return {ep.name: ep.load() for ep in entry_points(group=ENTRY_POINT_GROUP)}


def all_blocks() -> dict[str, Block]:
    """Every registered block, sorted by name (fp32 cores and published registries merged in).

    A name published twice is an error (``ValueError`` naming both owners), so that one
    registry can never silently shadow another's block.
    """
    found: dict[str, Block] = dict(_fp32_blocks())
    owners = dict.fromkeys(found, FP32_MODULE)
    sources = {"navgate.hw.blocks": REGISTRY, **published_registries()}
    for owner, registry in sources.items():
        for name, (target, description) in registry.items():
            if name in found:
                raise ValueError(f"block {name!r} is registered by both {owners[name]} "
                                 f"and {owner}")
            found[name] = Block(name, _lazy_factory(target), description, target)
            owners[name] = owner
    return {name: found[name] for name in sorted(found)}


def get_block(name: str) -> Block:
    """The block called ``name``; ``KeyError`` with the known names if there is none."""
    blocks = all_blocks()
    if name not in blocks:
        raise KeyError(f"unknown block {name!r}; known blocks: {', '.join(blocks)}")
    return blocks[name]
