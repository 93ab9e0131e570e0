"""Verilog emission and block descriptions for the synthesis flow.

Amaranth is imported inside the functions that need it: :func:`verilog_ports` reads emitted
Verilog as text, also on an install without the gateware extra.

``emit_verilog`` converts one Amaranth component to Verilog with
``amaranth.back.verilog.convert(..., emit_src=False)``; without source locations the text
depends only on the design, so the same block gives a byte-identical file every time. The top
module is named after the block.

``describe_block`` lists what a user of the emitted Verilog needs: every port with its
direction and width (``clk`` and ``rst`` included, payload field layout where the port is a
``lib.data`` view), ``LATENCY``, ``THROUGHPUT`` and the constructor parameters the instance was
built with.
"""

from __future__ import annotations

import inspect
import math
import re
from fractions import Fraction
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # Amaranth is imported where it is used: verilog_ports is plain text
    from amaranth.lib import data, wiring


def emit_verilog(component: wiring.Component, name: str) -> str:
    """Verilog text of ``component`` with top module ``name`` (deterministic)."""
    from amaranth.back import verilog

    if not name.isidentifier():
        raise ValueError(f"block name {name!r} is not a valid Verilog module name")
    return verilog.convert(component, name=name, emit_src=False)


def _layout_fields(layout: data.Layout) -> dict[str, Any]:
    from amaranth.hdl import Shape
    from amaranth.lib import data

    fields: dict[str, Any] = {}
    for key, field in layout:
        entry: dict[str, Any] = {"offset": field.offset, "width": field.width}
        shape = field.shape
        if isinstance(shape, data.Layout):
            entry["fields"] = _layout_fields(shape)
        else:
            entry["signed"] = Shape.cast(shape).signed
        fields[str(key)] = entry
    return fields


_HEADER = re.compile(r"^module\s+(\S+)\s*\(([^)]*)\);", re.MULTILINE)
_DECL = re.compile(r"^\s*(input|output)\s+(?:\[(\d+):0\]\s+)?\\?(\S+)\s*;", re.MULTILINE)


def verilog_ports(text: str, name: str) -> list[tuple[str, str, int]]:
    """``(port, direction, width)`` of module ``name`` in emitted Verilog, header order."""
    headers = {m.group(1): m for m in _HEADER.finditer(text)}
    if name not in headers:
        raise ValueError(f"module {name!r} not found in the Verilog text")
    header = headers[name]
    body_end = text.find("endmodule", header.end())
    body = text[header.end() : body_end]
    decls = {m.group(3): (m.group(1), int(m.group(2) or 0) + 1) for m in _DECL.finditer(body)}
    ports = []
    for port in header.group(2).split(","):
        port = port.strip().lstrip("\\")
        direction, width = decls[port]
        ports.append((port, direction, width))
    return ports


def port_list(component: wiring.Component, text: str, name: str) -> list[dict[str, Any]]:
    """Ports of the emitted module with direction, width, signedness and payload fields.

    Names, directions and widths are read from the Verilog itself (so ``clk``/``rst`` appear
    exactly when the design has them); signedness and ``lib.data`` field layouts come from the
    component's signature.
    """
    from amaranth.hdl import Value
    from amaranth.lib import data

    extra: dict[str, dict[str, Any]] = {}
    for path, _member, value in component.signature.flatten(component):
        port = "__".join(str(part) for part in path)
        if isinstance(value, data.View):
            extra[port] = {"fields": _layout_fields(data.Layout.cast(value.shape()))}
        else:
            extra[port] = {"signed": Value.cast(value).shape().signed}
    ports = []
    for port, direction, width in sorted(verilog_ports(text, name), key=_port_order):
        entry: dict[str, Any] = {"name": port, "direction": direction, "width": width}
        entry.update(extra.get(port, {}))
        ports.append(entry)
    return ports


def _port_order(port: tuple[str, str, int]) -> tuple[int, str]:
    # clock and reset first, then by name: stable and readable
    return ({"clk": 0, "rst": 1}.get(port[0], 2), port[0])


def _plain(value: Any) -> Any:
    if isinstance(value, bool | int | str) or value is None:
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Fraction):
        return float(value)
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    return str(value)


def parameters(component: wiring.Component) -> dict[str, Any]:
    """Constructor parameters of ``component`` as built (attribute ``name`` or ``_name``)."""
    params: dict[str, Any] = {}
    signature = inspect.signature(type(component).__init__)
    for name, parameter in list(signature.parameters.items())[1:]:
        if parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD):
            continue
        sentinel = object()
        value = getattr(component, name, sentinel)
        if value is sentinel:
            value = getattr(component, "_" + name, sentinel)
        if value is sentinel or callable(value):
            value = None if parameter.default is parameter.empty else parameter.default
        params[name] = _plain(value)
    return params


def throughput_fraction(component: Any) -> Fraction:
    """``THROUGHPUT`` (results per cycle) as an exact fraction."""
    value = component.THROUGHPUT
    if isinstance(value, float):
        return Fraction(value).limit_denominator(1 << 16)
    return Fraction(value)


def _plain_number(value: Fraction) -> int | float:
    return value.numerator if value.denominator == 1 else float(value)


def format_throughput(value: Fraction) -> str:
    """``1`` or ``1/18``: results per cycle."""
    return str(value.numerator) if value.denominator == 1 else f"{value}"


def describe_block(
    component: wiring.Component, name: str, description: str, text: str
) -> dict[str, Any]:
    """The contents of ``BLOCK.json`` (``text``: the Verilog emitted for ``component``)."""
    throughput = throughput_fraction(component)
    return {
        "block": name,
        "top_module": name,
        "description": description,
        "class": f"{type(component).__module__}.{type(component).__qualname__}",
        "latency_cycles": int(component.LATENCY),
        "throughput_per_cycle": float(throughput),
        "throughput": format_throughput(throughput),
        "initiation_interval_cycles": _plain_number(1 / throughput) if throughput else None,
        "parameters": parameters(component),
        "ports": port_list(component, text, name),
    }
