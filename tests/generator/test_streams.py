"""The batched random streams give numpy's numbers bit for bit (issue 43, item 1)."""

import numpy as np
import pytest

from simlidar.generator.simulate import SPLIT_IDS, sample_stream
from simlidar.generator.streams import Streams, words


@pytest.mark.parametrize("seed", [0, 1, 4242, 2**32 - 1, 2**32, 2**40 + 7, 2**63 - 1])
@pytest.mark.parametrize("split", ["train", "test", "sweep"])
@pytest.mark.parametrize("compiled", [False, True])
def test_every_draw_is_the_one_numpy_gives_each_sample(seed, split, compiled):
    """Doubles and float32 in the order the pipeline reads them, an odd float32 count (a 64-bit
    output's high half kept for the next float32, not for a double) and draws from some rows
    only, for indices with one 32-bit word and the largest a split can have; in numpy and by
    the compiled kernel."""
    index = np.array([0, 1, 2, 7, 1000, 4095, 4096, 10**9 - 1])
    streams = Streams(seed, SPLIT_IDS[split], index, compiled=compiled)
    some = np.array([1, 4, 7])
    draws = [
        streams.random(2),
        streams.random_float32((16, 16)),
        streams.random(20, some),
        streams.random_float32((3,)),
        streams.random(3),
        streams.random_float32((1,)),
        streams.random_float32((2, 3)),
    ]
    for row, i in enumerate(index):
        g = sample_stream(seed, split, int(i))
        expected = [g.random(2), g.random((16, 16), dtype=np.float32)]
        expected.append(g.random(20) if row in some else None)
        expected += [g.random(3, dtype=np.float32), g.random(3)]
        expected += [g.random(1, dtype=np.float32), g.random((2, 3), dtype=np.float32)]
        for k, (got, want) in enumerate(zip(draws, expected)):
            if want is None:
                continue
            mine = got[list(some).index(row)] if k == 2 else got[row]
            assert mine.dtype == want.dtype and np.array_equal(mine, want), (seed, split, i, k)


def test_words_are_numpys_and_out_of_range_values_are_refused():
    assert words(0) == [0] and words(2**32) == [0, 1] and words(2**64 - 1) == [2**32 - 1] * 2
    with pytest.raises(ValueError, match="non-negative"):
        words(-1)
    with pytest.raises(ValueError, match="2\\*\\*128"):
        Streams(2**128, 0, np.arange(2))
    with pytest.raises(ValueError, match="indices"):
        Streams(0, 0, np.array([2**32]))


def test_the_kernels_high_word_is_the_128_bit_products():
    from numba import njit

    from simlidar.generator.stream_kernels import mul_high

    high = njit(lambda a, b: mul_high(a, b))
    rng = np.random.default_rng(9)
    pairs = [(0, 0), (2**64 - 1, 2**64 - 1), (2**63, 2), (2**32, 2**32), (1, 2**64 - 1)]
    pairs += [tuple(int(v) for v in rng.integers(0, 2**64, 2, dtype=np.uint64)) for _ in range(50)]
    for a, b in pairs:
        assert int(high(np.uint64(a), np.uint64(b))) == (a * b) >> 64, (a, b)
