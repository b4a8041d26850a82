"""Every sample's random stream, numpy's bit for bit, made and drawn a batch at a time.

A sample's stream is ``np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed,
spawn_key=(split_id, index))))`` (:func:`simlidar.generator.simulate.sample_stream`). Made one
at a time, a stream costs about 11 us a sample on this project's machine (the SeedSequence's
hashing in Python objects, the Generator, a Python call per draw; issue 43). :class:`Streams`
does the same arithmetic on arrays, one element a sample, and gives the same numbers:

* numpy's ``SeedSequence`` (``numpy/random/bit_generator.pyx``): its pool of 4 words filled
  and mixed from the entropy (the seed's 32-bit words padded to 4, the split's, the index's)
  and ``generate_state(4, uint64)``. Its hash constants do not depend on the data, and every
  word but the index is the batch's own, so all but the index's mixing is done once;
* PCG64's seeding from those 4 words (``pcg64_set_seed``: state and increment as 128-bit
  integers, high word first) and its output (the XSL-RR function of a 128-bit LCG,
  ``numpy/random/src/pcg64/pcg64.h``), the 128-bit arithmetic in pairs of uint64;
* ``Generator.random``: a double from the top 53 bits of a 64-bit output; a float32 from the
  top 24 bits of a 32-bit one, which takes the low half of a 64-bit output and keeps the high
  half for the next float32 (a double leaves it there).

In numpy on arrays; on long runs, where the ray cast's compiled kernels are loaded anyway
(:func:`simlidar.sensor.raycast.compiled_for`), the draws go through a compiled kernel
(``compiled``: :func:`simlidar.generator.stream_kernels.draw`, the same integers). A short run
keeps numpy: the first kernel a process loads costs it about 0.4 s (numba's import and LLVM).
``tests/generator/test_streams.py`` holds every draw of both forms to numpy's.
"""

import numpy as np

_M32 = 0xFFFFFFFF
# numpy's SeedSequence constants (bit_generator.pyx)
_INIT_A, _MULT_A, _INIT_B, _MULT_B = 0x43B0D7E5, 0x931E8875, 0x8B51F9DD, 0x58F38DED
_MIX_MULT_L, _MIX_MULT_R, _XSHIFT, _POOL = 0xCA01F9DD, 0x4973F715, 16, 4
# PCG64's 128-bit multiplier (PCG_DEFAULT_MULTIPLIER_HIGH, _LOW)
_MULT_HIGH, _MULT_LOW = 2549297995355413924, 4865540595714422341
_U32, _S32 = np.uint64(_M32), np.uint64(32)
_DOUBLE = 1.0 / 9007199254740992.0  # 2**-53
_FLOAT = np.float32(1.0 / 16777216.0)  # 2**-24


def words(value: int) -> list[int]:
    """numpy's ``_int_to_uint32_array``: a non-negative integer as 32-bit words, low first."""
    if value < 0:
        raise ValueError(f"value={value}: expected a non-negative integer")
    out = [value & _M32]
    value >>= 32
    while value:
        out.append(value & _M32)
        value >>= 32
    return out


class _Hash:
    """SeedSequence's ``hashmix`` with its running constant, on ints or uint64 arrays."""

    def __init__(self):
        self.const = _INIT_A

    def __call__(self, value):
        const = self.const
        self.const = (const * _MULT_A) & _M32
        if isinstance(value, int):
            value = ((value ^ const) * self.const) & _M32
            return value ^ (value >> _XSHIFT)
        value = ((value ^ np.uint64(const)) * np.uint64(self.const)) & _U32
        return value ^ (value >> np.uint64(_XSHIFT))


def _mix(x, y):
    """SeedSequence's ``mix`` of two words (ints, or uint64 arrays of 32-bit values)."""
    if isinstance(x, int) and isinstance(y, int):
        result = (_MIX_MULT_L * x - _MIX_MULT_R * y) & _M32
        return result ^ (result >> _XSHIFT)
    x, y = np.asarray(x, np.uint64), np.asarray(y, np.uint64)
    result = (np.uint64(_MIX_MULT_L) * x - np.uint64(_MIX_MULT_R) * y) & _U32
    return result ^ (result >> np.uint64(_XSHIFT))


def _mul_high(a: np.ndarray, b: int) -> np.ndarray:
    """The high 64 bits of each 128-bit product a * b, a uint64 array, b below 2**64."""
    b_lo, b_hi = np.uint64(b & _M32), np.uint64(b >> 32)
    a_lo, a_hi = a & _U32, a >> _S32
    lo_lo, hi_lo = a_lo * b_lo, a_hi * b_lo
    cross = (lo_lo >> _S32) + (hi_lo & _U32) + a_lo * b_hi
    return a_hi * b_hi + (hi_lo >> _S32) + (cross >> _S32)


def _step(hi, lo, inc_hi, inc_lo):
    """One LCG step, state * multiplier + increment mod 2**128: the new (hi, lo)."""
    new_hi = _mul_high(lo, _MULT_LOW) + hi * np.uint64(_MULT_LOW) + lo * np.uint64(_MULT_HIGH)
    new_lo = lo * np.uint64(_MULT_LOW)
    out_lo = new_lo + inc_lo
    return new_hi + inc_hi + (out_lo < new_lo), out_lo


def _output(hi: np.ndarray, lo: np.ndarray) -> np.ndarray:
    """PCG's XSL-RR output of 128-bit states."""
    value = hi ^ lo
    rot = hi >> np.uint64(58)
    return (value >> rot) | (value << ((np.uint64(64) - rot) & np.uint64(63)))


def _float32(word: np.ndarray) -> np.ndarray:
    """numpy's ``next_float`` of 32-bit outputs (held in uint64)."""
    return (word >> np.uint64(8)).astype(np.float32) * _FLOAT


class Streams:
    """The random streams of samples ``indices`` of one split (:func:`simlidar.generator.
    simulate.sample_stream`), drawn together: ``random`` and ``random_float32`` give what each
    sample's own ``Generator.random`` would, in the same order; ``compiled``: drawn by the
    compiled kernel (the same numbers)."""

    def __init__(self, seed: int, split_id: int, indices: np.ndarray, compiled: bool = False):
        run = words(int(seed))
        if len(run) > _POOL:
            raise ValueError(f"seed={seed}: expected an integer below 2**128")
        indices = np.asarray(indices, np.int64)
        if len(indices) and (indices.min() < 0 or indices.max() > _M32):
            raise ValueError("indices: expected integers in [0, 2**32)")
        # the entropy: the seed padded to the pool (numpy pads it when there is a spawn key),
        # the split, the index (one word below 2**32); all but the index the batch's own
        entropy = run + [0] * (_POOL - len(run)) + words(int(split_id))
        mix = _Hash()
        pool = [mix(word) for word in entropy[:_POOL]]
        for source in range(_POOL):
            for target in range(_POOL):
                if source != target:
                    pool[target] = _mix(pool[target], mix(pool[source]))
        for word in [*entropy[_POOL:], indices.astype(np.uint64)]:
            for target in range(_POOL):
                pool[target] = _mix(pool[target], mix(word))
        # generate_state(4, uint64): 8 words from the pool in turn, two to a uint64, low first
        const, seeded = _INIT_B, []
        for w in range(4):
            pair = np.zeros(len(indices), np.uint64)
            for half in range(2):
                value = np.asarray(pool[(2 * w + half) % _POOL], np.uint64) ^ np.uint64(const)
                const = (const * _MULT_B) & _M32
                value = (value * np.uint64(const)) & _U32
                pair |= (value ^ (value >> np.uint64(_XSHIFT))) << np.uint64(32 * half)
            seeded.append(pair)
        # pcg64_set_seed: state 0, increment (seq << 1) | 1, a step, + seed, a step
        one = np.uint64(1)
        self.inc_hi = (seeded[2] << one) | (seeded[3] >> np.uint64(63))
        self.inc_lo = (seeded[3] << one) | one
        zero = np.zeros(len(indices), np.uint64)
        hi, lo = _step(zero, zero, self.inc_hi, self.inc_lo)
        low = lo + seeded[1]
        self.hi, self.lo = _step(hi + seeded[0] + (low < lo), low, self.inc_hi, self.inc_lo)
        # a 32-bit half kept for the next float32: every stream draws its float32 together,
        # so they all hold one or none
        self.buffered = None
        self.compiled = compiled

    def _outputs(self, rows, count: int) -> np.ndarray:
        """(len(rows), count) uint64: the streams' next ``count`` 64-bit outputs."""
        if self.compiled:
            from simlidar.generator.stream_kernels import draw

            every = np.arange(len(self.hi)) if isinstance(rows, slice) else rows
            return draw(self.hi, self.lo, self.inc_hi, self.inc_lo, every, count)
        hi, lo = self.hi[rows], self.lo[rows]
        inc_hi, inc_lo = self.inc_hi[rows], self.inc_lo[rows]
        out = np.empty((len(hi), count), np.uint64)
        for j in range(count):
            hi, lo = _step(hi, lo, inc_hi, inc_lo)
            out[:, j] = _output(hi, lo)
        self.hi[rows], self.lo[rows] = hi, lo
        return out

    def random(self, count: int, rows=None) -> np.ndarray:
        """(len(rows), count) float64 in [0, 1): each stream's next ``count`` doubles (every
        stream's when ``rows`` is None)."""
        rows = slice(None) if rows is None else np.asarray(rows, np.int64)
        return (self._outputs(rows, int(count)) >> np.uint64(11)) * _DOUBLE

    def random_float32(self, shape: tuple[int, ...]) -> np.ndarray:
        """(N, *shape) float32 in [0, 1): each stream's next ``prod(shape)`` float32."""
        count = int(np.prod(shape))
        out = np.empty((len(self.hi), count), np.float32)
        first = 0
        if self.buffered is not None and count:
            out[:, 0], self.buffered, first = _float32(self.buffered), None, 1
        pairs = (count - first + 1) // 2
        full = self._outputs(slice(None), pairs)
        halves = np.empty((len(self.hi), 2 * pairs), np.uint64)
        halves[:, 0::2], halves[:, 1::2] = full & _U32, full >> _S32
        out[:, first:] = _float32(halves[:, : count - first])
        if 2 * pairs > count - first:  # an odd count: the last output's high half is kept
            self.buffered = halves[:, -1]
        return out.reshape((len(self.hi), *shape))
