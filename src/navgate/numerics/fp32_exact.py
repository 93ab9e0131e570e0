"""Exact scalar reference for the navgate binary32 semantics (slow; for verification).

Independent of :mod:`navgate.numerics.fp32`: operands are decoded to exact rationals
(:class:`fractions.Fraction`), the operation is carried out exactly (square roots with
:func:`math.isqrt` plus a sticky bit), and the exact value is rounded to 24 significant
bits, ties to even, with unbounded exponent, then range-checked (< 2^-126 -> signed zero,
>= 2^128 -> signed infinity). Special values follow IEEE 754 as in docs/numerics.md.
Used by tests/numerics and available to gateware tests as a second opinion.
"""

from __future__ import annotations

import math
from fractions import Fraction

QNAN = 0x7FC00000
_INF = 0x7F800000


def decode(bits: int):
    """-> ("nan",), ("inf", sign) or ("num", sign, Fraction >= 0); subnormals flush."""
    bits = int(bits)
    s = bits >> 31
    e = (bits >> 23) & 0xFF
    f = bits & 0x7FFFFF
    if e == 0xFF:
        return ("nan",) if f else ("inf", s)
    if e == 0:
        return ("num", s, Fraction(0))
    return ("num", s, Fraction((1 << 23) | f) * Fraction(2) ** (e - 150))


def round_int(sig: int, exp2: int, sign: int, sticky: bool = False) -> int:
    """Round ``(sig + delta) * 2**exp2`` (0 < delta < 1 when sticky) to binary32 bits."""
    if sig == 0 and not sticky:
        return sign << 31
    if sig.bit_length() < 26:  # widen so that sticky lies strictly below the round bit
        k = 26 - sig.bit_length()
        sig <<= k
        exp2 -= k
    drop = sig.bit_length() - 24
    q = sig >> drop
    rem = sig & ((1 << drop) - 1)
    half = 1 << (drop - 1)
    if rem > half or (rem == half and (sticky or q & 1)):
        q += 1
    if q == 1 << 24:
        q >>= 1
        drop += 1
    e_unb = exp2 + drop + 23  # value = q * 2^(exp2+drop), q in [2^23, 2^24)
    if e_unb < -126:
        return sign << 31
    if e_unb > 127:
        return (sign << 31) | _INF
    return (sign << 31) | ((e_unb + 127) << 23) | (q & 0x7FFFFF)


def round_fraction(x: Fraction, sign: int | None = None) -> int:
    """Round an exact rational to binary32 bits (sign of zero from ``sign``)."""
    if sign is None:
        sign = 1 if x < 0 else 0
    x = abs(x)
    if x == 0:
        return sign << 31
    num, den = x.numerator, x.denominator
    k = 30 - (num.bit_length() - den.bit_length())  # quotient gets >= 29 bits
    if k >= 0:
        q, r = divmod(num << k, den)
    else:
        q, r = divmod(num, den << -k)
    return round_int(q, -k, sign, r != 0)


def _value(d):
    return -d[2] if d[1] else d[2]


def add(a: int, b: int) -> int:
    da, db = decode(a), decode(b)
    if da[0] == "nan" or db[0] == "nan":
        return QNAN
    if da[0] == "inf" and db[0] == "inf":
        return QNAN if da[1] != db[1] else (da[1] << 31) | _INF
    if da[0] == "inf":
        return (da[1] << 31) | _INF
    if db[0] == "inf":
        return (db[1] << 31) | _INF
    s = _value(da) + _value(db)
    if s == 0:
        both_zero = da[2] == 0 and db[2] == 0
        return (1 << 31) if (both_zero and da[1] and db[1]) else 0
    return round_fraction(s)


def sub(a: int, b: int) -> int:
    return add(a, int(b) ^ 0x80000000) if decode(b)[0] != "nan" else QNAN


def mul(a: int, b: int) -> int:
    da, db = decode(a), decode(b)
    if da[0] == "nan" or db[0] == "nan":
        return QNAN
    sign = da[1] ^ db[1]
    if da[0] == "inf" or db[0] == "inf":
        other = db if da[0] == "inf" else da
        if other[0] == "num" and other[2] == 0:
            return QNAN
        return (sign << 31) | _INF
    return round_fraction(da[2] * db[2], sign)


def div(a: int, b: int) -> int:
    da, db = decode(a), decode(b)
    if da[0] == "nan" or db[0] == "nan":
        return QNAN
    sign = da[1] ^ db[1]
    if da[0] == "inf":
        return QNAN if db[0] == "inf" else (sign << 31) | _INF
    if db[0] == "inf":
        return sign << 31
    if db[2] == 0:
        return QNAN if da[2] == 0 else (sign << 31) | _INF
    return round_fraction(da[2] / db[2], sign)


def sqrt(a: int) -> int:
    da = decode(a)
    if da[0] == "nan":
        return QNAN
    if da[0] == "inf":
        return QNAN if da[1] else _INF
    if da[2] == 0:
        return da[1] << 31
    if da[1]:
        return QNAN
    x = da[2]  # = m * 2^e with m odd integer
    num, den = x.numerator, x.denominator
    e = -(den.bit_length() - 1)  # den is a power of two
    m = num
    if e % 2:
        m <<= 1
        e -= 1
    # sqrt(m * 2^e) = sqrt(m * 4^t) * 2^(e/2 - t); choose t for >= 30 result bits
    t = max(0, 30 - m.bit_length() // 2)
    big = m << (2 * t)
    r = math.isqrt(big)
    return round_int(r, e // 2 - t, 0, r * r != big)


def from_int(i: int, scale_exp: int = 0) -> int:
    i = int(i)
    return round_fraction(Fraction(i) * Fraction(2) ** scale_exp, 1 if i < 0 else 0)


def to_int(a: int, width: int, scale_exp: int = 0) -> tuple[int, bool]:
    """Round-ties-even conversion to a saturated signed ``width``-bit integer."""
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    d = decode(a)
    if d[0] == "nan":
        return 0, True
    if d[0] == "inf":
        return (lo if d[1] else hi), True
    v = _value(d) * Fraction(2) ** scale_exp
    r = round(v)  # Fraction.__round__ rounds half to even
    if r > hi:
        return hi, True
    if r < lo:
        return lo, True
    return int(r), False
