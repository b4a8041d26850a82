"""The compiled (numba) kernel of the batched random streams: PCG64's draws, a sample's at a
time (:class:`simlidar.generator.streams.Streams`, where long runs take it).

The numpy form steps every stream of a batch together, one output at a time, with a dozen
array operations a step (its 128-bit products in 32-bit halves). The kernel walks one stream
after the other, its state in registers, the 128-bit product's high word by one
multiplication (:func:`mul_high`, LLVM's 128-bit integers). Integer arithmetic wraps the same
way in both, so the outputs are the same numbers by construction;
``tests/generator/test_streams.py`` holds both forms to numpy's own ``Generator``.
"""

import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import types
from numba.extending import intrinsic

# PCG64's 128-bit multiplier (PCG_DEFAULT_MULTIPLIER_HIGH, _LOW), as the numpy form's
_MULT_HIGH, _MULT_LOW = np.uint64(2549297995355413924), np.uint64(4865540595714422341)
_ONE, _ROTATE, _BITS, _MASK = np.uint64(1), np.uint64(58), np.uint64(64), np.uint64(63)


@intrinsic
def mul_high(typingctx, a, b):
    """The high 64 bits of the 128-bit product of two uint64 (one ``mul`` on x86-64);
    callable from numba kernels only."""
    sig = types.uint64(types.uint64, types.uint64)

    def codegen(context, builder, signature, args):
        wide = ir.IntType(128)
        product = builder.mul(builder.zext(args[0], wide), builder.zext(args[1], wide))
        return builder.trunc(builder.lshr(product, ir.Constant(wide, 64)), ir.IntType(64))

    return sig, codegen


@njit(cache=True, nogil=True)
def draw(hi, lo, inc_hi, inc_lo, rows, count):
    """The next ``count`` 64-bit outputs of the streams ``rows``, their states advanced in
    place: numpy's ``pcg64_next64`` (an LCG step mod 2**128, then the XSL-RR output).

    hi, lo : (N,) uint64, each stream's 128-bit state, high and low words (updated)
    inc_hi, inc_lo : (N,) uint64, each stream's increment
    rows : (R,) int64, the streams drawn from, in order
    count : outputs a stream
    returns : (R, count) uint64
    """
    out = np.empty((rows.shape[0], count), np.uint64)
    for a in range(rows.shape[0]):
        r = rows[a]
        h, low = hi[r], lo[r]
        add_hi, add_lo = inc_hi[r], inc_lo[r]
        for j in range(count):
            new_hi = mul_high(low, _MULT_LOW) + h * _MULT_LOW + low * _MULT_HIGH
            new_lo = low * _MULT_LOW
            low = new_lo + add_lo
            h = new_hi + add_hi
            if low < new_lo:  # the carry out of the low words
                h += _ONE
            value = h ^ low
            rot = h >> _ROTATE
            out[a, j] = (value >> rot) | (value << ((_BITS - rot) & _MASK))
        hi[r], lo[r] = h, low
    return out
