"""The JSON summary every run writes beside its report, and the no-silent-NaN check.

A dictionary entry that does not apply to a run is left out, never ``null``; non-finite floats
become ``null`` so the file stays valid JSON and the command then fails (docs/conventions.md).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any


def _json_ready(value: Any) -> Any:
    """Convert NumPy scalars/arrays and non-finite floats into plain JSON values.

    A dictionary entry whose value is ``None`` (not applicable to this run, such as the NIS
    of a run without TRN fixes) is left out: a summary never holds ``null`` for "does not
    apply"; the key is absent (docs/conventions.md). Non-finite floats become ``null`` so
    the file stays valid JSON, and the commands then fail (:func:`non_finite_keys`).
    """
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, dict):
        return {str(k): _json_ready(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def non_finite_keys(summary: Any, prefix: str = "") -> list[str]:
    """Dotted keys of every NaN/inf float in ``summary`` (for the no-silent-NaN rule)."""
    if hasattr(summary, "tolist"):
        summary = summary.tolist()
    found = []
    if isinstance(summary, dict):
        for k, v in summary.items():
            found += non_finite_keys(v, f"{prefix}{k}.")
    elif isinstance(summary, (list, tuple)):
        for i, v in enumerate(summary):
            found += non_finite_keys(v, f"{prefix}{i}.")
    elif isinstance(summary, float) and not math.isfinite(summary):
        found.append(prefix.rstrip("."))
    return found


def write_summary(out_dir: Path, summary: dict[str, Any], name: str = "summary.json") -> Path:
    """Write a run's machine-readable summary beside its report."""
    path = Path(out_dir) / name
    path.write_text(json.dumps(_json_ready(summary), indent=2, sort_keys=False) + "\n")
    return path
