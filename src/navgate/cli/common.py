"""Shared pieces of the command line: the error type and output-directory handling."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any


class CliError(Exception):
    """An expected failure (bad input, bad option value): printed as one line, exit 2."""


def prepare_out_dir(path: str | Path) -> Path:
    """Create the output directory (and parents), failing with a clear CliError."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise CliError(f"cannot create output directory {out}: {error.strerror}") from None
    if not out.is_dir():
        raise CliError(f"output path {out} exists and is not a directory")
    return out


def _json_ready(value: Any) -> Any:
    """Convert NumPy scalars/arrays and non-finite floats into plain JSON values."""
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, dict):
        return {str(k): _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_summary(out_dir: Path, summary: dict[str, Any], name: str = "summary.json") -> Path:
    """Write a run's machine-readable summary beside its report."""
    path = Path(out_dir) / name
    path.write_text(json.dumps(_json_ready(summary), indent=2, sort_keys=False) + "\n")
    return path
