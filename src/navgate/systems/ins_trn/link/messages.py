"""The messages of the PS <-> Pi link (docs/seed000-link.md): kinds, bodies, and the exact
encoding of float64 arrays.

Every body is a msgpack map. Arrays of float64 travel as little-endian raw bytes (msgpack
``bin``): exact to the bit, a third of the size of msgpack floats, and cheap to decode on the
Pi. Scalars are msgpack float64 (NaN and infinities allowed), strings UTF-8.

The PS owns all navigation state: the filter, the integrity monitor and the correlator's two
state words (``used_until``: samples up to this time have informed an accepted fix;
``widen``: the search-window factor after a reinitialisation). They travel in every request
and come back in the fix, so the service is stateless between requests: a restarted Pi
answers exactly as the one before it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

HELLO = 1  #: PS -> Pi: {"client": str, "version": int}
CAPABILITIES = 2  #: Pi -> PS: {"methods": [...], "terrain": str, "posts": [r, c], ...}
PROFILE_REQUEST = 3  #: PS -> Pi: see :func:`profile_request`
FIX = 4  #: Pi -> PS: see :func:`fix_body`
HEARTBEAT = 5  #: either way: {"time": float}
ERROR = 6  #: Pi -> PS: {"id": int | None, "error": str}
STATUS_REQUEST = 7  #: PS -> Pi: {}
STATUS = 8  #: Pi -> PS: the service's counters

NAMES = {HELLO: "hello", CAPABILITIES: "capabilities", PROFILE_REQUEST: "profile request",
         FIX: "fix", HEARTBEAT: "heartbeat", ERROR: "error", STATUS_REQUEST: "status request",
         STATUS: "status"}


class MessageError(ValueError):
    """A body that does not hold what its kind promises (counted as a bad message)."""


def pack_array(a) -> bytes:
    return np.ascontiguousarray(a, dtype="<f8").tobytes()


def unpack_array(b, name: str, size: int | None = None) -> np.ndarray:
    if not isinstance(b, bytes | bytearray) or len(b) % 8:
        raise MessageError(f"{name}: not an array of float64")
    a = np.frombuffer(b, dtype="<f8").astype(np.float64)
    if size is not None and a.size != size:
        raise MessageError(f"{name}: {a.size} values, expected {size}")
    return a


def profile_request(request_id: int, *, method: str, config: dict, tangent, time, pos_n,
                    pos_e, h_terrain, sigma_max: float, prior_cov, used_until: float,
                    widen: float, t_request: float) -> dict:
    """A TRN request: the profile (INS positions about ``tangent``, terrain heights, time
    tags), the prior (2 x 2 horizontal covariance, largest sigma) and the correlator state."""
    return {"id": int(request_id), "method": method, "config": config,
            "tangent": [float(x) for x in tangent], "time": pack_array(time),
            "pos_n": pack_array(pos_n), "pos_e": pack_array(pos_e),
            "h_terrain": pack_array(h_terrain), "sigma_max": float(sigma_max),
            "prior_cov": None if prior_cov is None else pack_array(np.asarray(prior_cov)),
            "used_until": float(used_until), "widen": float(widen),
            "t_request": float(t_request)}


def read_profile_request(body) -> dict:
    """The request's fields as arrays and floats; :class:`MessageError` if malformed."""
    if not isinstance(body, dict):
        raise MessageError("profile request: body is not a map")
    try:
        n = len(body["time"]) // 8
        out = {"id": int(body["id"]), "method": str(body["method"]),
               "config": dict(body["config"] or {}),
               "tangent": [float(x) for x in body["tangent"]],
               "sigma_max": float(body["sigma_max"]), "used_until": float(body["used_until"]),
               "widen": float(body["widen"]), "t_request": float(body["t_request"])}
        for name in ("time", "pos_n", "pos_e", "h_terrain"):
            out[name] = unpack_array(body[name], name, n)
        out["prior_cov"] = (None if body["prior_cov"] is None
                            else unpack_array(body["prior_cov"], "prior_cov", 4).reshape(2, 2))
    except (KeyError, TypeError, ValueError) as error:
        if isinstance(error, MessageError):
            raise
        raise MessageError(f"profile request: {error}") from None
    if len(out["tangent"]) != 3:
        raise MessageError("profile request: tangent must be [lat0, lon0, h0]")
    return out


def fix_body(request_id: int, result, used_until: float, widen: float,
             service_time_s: float) -> dict:
    """A correlator result (navgate.trn TercomResult / PmfResult) and the new state words."""
    fields = {}
    for f in dataclasses.fields(result):
        value = getattr(result, f.name)
        if isinstance(value, np.ndarray):
            value = {"shape": list(value.shape), "data": pack_array(value)}
        elif isinstance(value, np.generic):
            value = value.item()
        fields[f.name] = value
    return {"id": int(request_id), "result": fields, "used_until": float(used_until),
            "widen": float(widen), "service_time_s": float(service_time_s)}


def read_fix(body, result_type) -> tuple[int, object, float, float]:
    """(request id, result of ``result_type``, used_until, widen) of a fix body."""
    if not isinstance(body, dict):
        raise MessageError("fix: body is not a map")
    try:
        values = {}
        raw = body["result"]
        for f in dataclasses.fields(result_type):
            if f.name not in raw:
                continue
            value = raw[f.name]
            if isinstance(value, dict) and "data" in value:
                value = unpack_array(value["data"], f.name).reshape(value["shape"])
            values[f.name] = value
        return (int(body["id"]), result_type(**values), float(body["used_until"]),
                float(body["widen"]))
    except (KeyError, TypeError, ValueError) as error:
        if isinstance(error, MessageError):
            raise
        raise MessageError(f"fix: {error}") from None
