"""Bit-true numerics: the exact arithmetic the navgate gateware implements.

- :mod:`navgate.numerics.fp32`: IEEE-754 binary32 on uint32 bit patterns (round to
  nearest even, flush-to-zero inputs, tininess after rounding, canonical NaN).
- :mod:`navgate.numerics.fp32_exact`: slow exact (Fraction/integer) scalar reference.
- :mod:`navgate.numerics.fixed`: signed Q formats, seed 004's full/truncated add and mul.
- :mod:`navgate.numerics.cordic`: integer CORDIC (atan2/magnitude, cos/sin) and its
  worst-case error bounds.
- :mod:`navgate.numerics.goldschmidt`: fixed-point Goldschmidt reciprocal and division.

docs/numerics.md is the specification (formats, rounding, deviations, error bounds).
"""

from navgate.numerics.cordic import (
    angle_to_radians,
    atan_table,
    cordic_error_bound,
    cordic_gain,
    cordic_rotation,
    cordic_rotation_error_bound,
    cordic_vectoring,
    radians_to_angle,
)
from navgate.numerics.fixed import (
    QFormat,
    fits,
    fixed_abs,
    fixed_add,
    fixed_add_full,
    fixed_add_trunc,
    fixed_mul,
    fixed_mul_full,
    fixed_mul_trunc,
    fixed_neg,
    fixed_sub,
    fixed_sub_full,
    fixed_sub_trunc,
    mul_full_format,
    quantize,
    rescale,
    saturate,
    to_float,
    wrap,
)
from navgate.numerics.fp32 import (
    MAX_NORMAL,
    MIN_NORMAL,
    NEG_INF,
    NEG_ZERO,
    POS_INF,
    POS_ZERO,
    QNAN,
    bits_to_f32,
    f32_to_bits,
    flush_subnormal,
    fp32_abs,
    fp32_add,
    fp32_compare,
    fp32_div,
    fp32_from_fixed,
    fp32_from_int,
    fp32_mul,
    fp32_neg,
    fp32_sqrt,
    fp32_sub,
    fp32_to_fixed,
    fp32_to_int,
    is_inf,
    is_nan,
    is_subnormal,
    is_zero,
)
from navgate.numerics.goldschmidt import (
    goldschmidt_divide,
    goldschmidt_error_bound,
    goldschmidt_normalised,
    goldschmidt_reciprocal,
    goldschmidt_seed_table,
    seed_error,
)

__all__ = [
    "QNAN", "POS_INF", "NEG_INF", "POS_ZERO", "NEG_ZERO", "MIN_NORMAL", "MAX_NORMAL",
    "f32_to_bits", "bits_to_f32", "is_nan", "is_inf", "is_zero", "is_subnormal",
    "flush_subnormal", "fp32_add", "fp32_sub", "fp32_mul", "fp32_div", "fp32_sqrt",
    "fp32_neg", "fp32_abs", "fp32_compare", "fp32_from_int", "fp32_to_int",
    "fp32_from_fixed", "fp32_to_fixed",
    "QFormat", "quantize", "to_float", "saturate", "wrap", "fits", "rescale",
    "fixed_add", "fixed_sub", "fixed_add_full", "fixed_sub_full", "fixed_add_trunc",
    "fixed_sub_trunc", "fixed_neg", "fixed_abs", "fixed_mul", "fixed_mul_full",
    "fixed_mul_trunc", "mul_full_format",
    "atan_table", "cordic_gain", "cordic_vectoring", "cordic_rotation",
    "cordic_error_bound", "cordic_rotation_error_bound", "angle_to_radians",
    "radians_to_angle",
    "goldschmidt_seed_table", "goldschmidt_normalised", "goldschmidt_reciprocal",
    "goldschmidt_divide", "goldschmidt_error_bound", "seed_error",
]
