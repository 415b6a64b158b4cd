"""`exp` and `log` for the numba kernels, in arithmetic that LLVM vectorises.

numba's `math.exp` and `math.log` call libm, one double a call: a loop over them cannot be
vectorised, and the blend of a 256-row batch spends most of its time there (llvmlite on the
package index is built without Intel's SVML, the one vector maths library numba would use).
These two are plain arithmetic on the bits of a double, inlined into the caller's loop, so a
loop over a block of values runs 4 (AVX2) or 8 (AVX-512) of them at a time. Used on blocks
(`policy.blend_kernel`), each costs about a sixth of libm's call.

Accuracy, against numpy's (tests/policy/test_kernel_maths.py, which also checks the edges):

- `exp(x)`: within 2 ulp wherever e^x is a normal double, and correctly rounded from that where
  it is subnormal (the same numbers as numpy's there, or one subnormal step, 5e-324, away);
  0 below -745.14; +inf above `EXP_OVERFLOW`; NaN for NaN.
- `log(x)`: within 4 ulp for every positive double, subnormal ones included; log(0) = -inf,
  log(+inf) = +inf, NaN for negative x and NaN.

Method: exp: x = k ln2 + r with k = round(x / ln2) and |r| <= ln2/2 (ln2 in two parts, so
k ln2 is exact), e^r by its Taylor series to r^13 (next term below 1e-17 relative), times 2^k
built in the exponent bits. log: x = 2^k m with m in [sqrt(1/2), sqrt(2)), log m = 2 atanh(s) with
s = (m - 1)/(m + 1), |s| <= 0.172, by its series to s^23, plus k ln2 in two parts. Integer
parts are moved through the bits of doubles (adding 2^52 + 2^51), never converted: AVX2 has no
vector conversion between doubles and 64-bit integers.

numba's on-disk cache of a kernel is keyed by the kernel's own file only: after a change here,
delete `policy/__pycache__/*.nbi` so that the kernels inlining these compile again.
"""

from __future__ import annotations

import math
from typing import Any

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

LN2_HI = 6.93147180369123816490e-01  # ln 2 to 32 bits: k * LN2_HI is exact for |k| < 2^21
LN2_LO = 1.90821492927058770002e-10  # ln 2 - LN2_HI
LOG2_E = 1.44269504088896338700e00  # 1 / ln 2
ROUNDER = 6755399441055744.0  # 2^52 + 2^51: v + ROUNDER holds round(v) in its low bits
TWO_52 = 4503599627370496.0  # 2^52, whose double has the integer n in its low bits at 2^52 + n
SQRT_2 = 1.4142135623730951
SMALLEST_NORMAL = 2.2250738585072014e-308
EXP_LOWEST = -746.0  # e^x rounds to 0 below ln(2^-1075) = -745.13...
EXP_OVERFLOW = 709.782712893384  # ln(largest double): above it, exp is +inf
SUBNORMAL_SCALE = 18014398509481984.0  # 2^54: a subnormal times it is normal

# Taylor coefficients 1/n! of e^r, n = 2..13
E2, E3, E4, E5, E6, E7, E8, E9, E10, E11, E12, E13 = (1.0 / math.factorial(n) for n in range(2, 14))
# 2 / (2j + 1) of 2 atanh(s) = log((1 + s) / (1 - s)), j = 0..11
L1, L3, L5, L7, L9, L11, L13, L15, L17, L19, L21, L23 = (2.0 / n for n in range(1, 24, 2))


def _bitcast(source: types.Type, target: types.Type, llvm_target: ir.Type) -> Any:
    """A numba function of one `source` value returning the `target` value with the same 64
    bits (a reinterpretation, no conversion: LLVM's bitcast)."""

    def typing(typingctx, value):
        def codegen(context, builder, signature, args):
            return builder.bitcast(args[0], llvm_target)

        return target(source), codegen

    return intrinsic(typing)


_double_from_bits = _bitcast(types.int64, types.float64, ir.DoubleType())
_bits_of_double = _bitcast(types.float64, types.int64, ir.IntType(64))


@njit(inline="always", error_model="numpy")
def exp(x):
    """e^x (module docstring: 1 ulp, 0 below `EXP_UNDERFLOW`)."""
    v = min(max(x, EXP_LOWEST), EXP_OVERFLOW)
    shifted = v * LOG2_E + ROUNDER
    k = shifted - ROUNDER  # round(v / ln 2), exactly
    r = (v - k * LN2_HI) - k * LN2_LO
    r2 = r * r
    r4 = r2 * r2
    series = (
        1.0
        + r
        + r2 * (E2 + r * E3 + r2 * (E4 + r * E5))
        + r4 * r2 * (E6 + r * E7 + r2 * (E8 + r * E9) + r4 * (E10 + r * E11 + r2 * (E12 + r * E13)))
    )
    # 2^k into exponent fields: the low bits of `shifted` hold k (past ROUNDER's own). Two
    # factors 2^j and 2^(k-j), j = round(k/2): k runs from -1076 to 1024, beyond one field's
    # range; the last product rounds once, to a subnormal number where e^x is one.
    k_bits = _bits_of_double(shifted) - _bits_of_double(ROUNDER)
    j_bits = _bits_of_double(k * 0.5 + ROUNDER) - _bits_of_double(ROUNDER)
    result = series * _double_from_bits((j_bits + 1023) << 52)
    result = result * _double_from_bits((k_bits - j_bits + 1023) << 52)
    if x > EXP_OVERFLOW:
        result = math.inf
    if x != x:  # NaN
        result = x
    return result


@njit(inline="always", error_model="numpy")
def log(x):
    """The natural logarithm of x (module docstring: 4 ulp; -inf at 0, NaN below)."""
    subnormal = x < SMALLEST_NORMAL
    v = x * SUBNORMAL_SCALE if subnormal else x
    bits = _bits_of_double(v)
    # the biased exponent as a double: 2^52 + e has e in its low bits
    biased = _double_from_bits((bits >> 52) | _bits_of_double(TWO_52)) - TWO_52
    m = _double_from_bits((bits & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000)  # in [1, 2)
    high = m > SQRT_2
    m = m * 0.5 if high else m
    k = biased - (1022.0 if high else 1023.0) - (54.0 if subnormal else 0.0)
    f = m - 1.0  # exact (m within a factor 2 of 1)
    s = f / (2.0 + f)
    s2 = s * s
    s4 = s2 * s2
    series = (
        L1
        + s2 * (L3 + s2 * L5)
        + s4 * s2 * (L7 + s2 * L9 + s4 * (L11 + s2 * L13))
        + s4 * s4 * s4 * s2 * (L15 + s2 * L17 + s4 * (L19 + s2 * L21) + s4 * s4 * L23)
    )
    result = k * LN2_HI + (s * series + k * LN2_LO)
    if x == 0.0:
        result = -math.inf
    if x == math.inf:
        result = math.inf
    if not x >= 0.0:  # negative or NaN
        result = math.nan
    return result
