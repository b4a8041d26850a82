"""The compiled TTFS kernels (simlidar.models.ttfs_kernels) against the torch form, their
oracle (ttfs.dense_torch; tests/models/test_ttfs_torch.py holds it to them through the
dispatch, in float32 too): the same spikes (the same neurons silent, the same causal sets) and
gradients to float rounding, on random batches with ties, silent inputs, all-silent rows and
empty batches, for dense and convolutional layers."""

import os
import subprocess
import sys

import numba
import numpy as np
import pytest
import torch

from simlidar.models import ttfs, ttfs_kernels


def _run(layer, z, w, seed: int):
    z, w = z.clone().requires_grad_(), w.clone().requires_grad_()
    out = layer(z, w)
    fired = torch.isfinite(out)
    weights = torch.randn(
        out.shape, generator=torch.Generator().manual_seed(seed), dtype=torch.float64
    )
    weights = weights.to(z.dtype)
    (torch.where(fired, out, 0.0) * weights).sum().backward()
    return out.detach(), z.grad, w.grad


@pytest.mark.parametrize(("rows", "n_in", "n_out"), [(40, 30, 12), (7, 256, 50), (0, 10, 4)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_kernels_give_the_reference_spikes_and_gradients(rows, n_in, n_out, seed, dense_case):
    z, w = dense_case(rows, n_in, n_out, seed)
    ref = _run(ttfs.dense_torch, z, w, seed)
    fast = _run(ttfs.dense, z, w, seed)
    assert torch.equal(torch.isfinite(ref[0]), torch.isfinite(fast[0]))  # the same silent set
    fired = torch.isfinite(ref[0])
    assert torch.allclose(ref[0][fired], fast[0][fired], rtol=1e-12, atol=0)
    for a, b in zip(ref[1:], fast[1:]):
        assert torch.allclose(a, b, rtol=1e-10, atol=1e-10)
    if rows:
        assert 0 < fired.float().mean() < 1  # both firing and silent neurons were tested


@pytest.mark.parametrize("seed", [0, 3])
def test_float32_inputs_get_float64_decisions(seed, dense_case):
    """The kernels sum in float64: on float32 inputs their spikes are the float64 ones rounded
    to float32, where float32 sums lose digits near the threshold (seed 3: one neuron of
    24,000 fired in float64 and was silent in the float32 batched reference that the torch
    form replaced; test_ttfs_torch.py finds such batches for the torch form's own sums)."""
    z, w = dense_case(60, 256, 400, seed, torch.float32)
    fast = _run(ttfs.dense, z, w, seed)
    exact = _run(ttfs.dense_torch, z.double(), w.double(), seed)
    assert torch.equal(torch.isfinite(fast[0]), torch.isfinite(exact[0]))
    fired = torch.isfinite(exact[0])
    assert torch.allclose(fast[0][fired].double(), exact[0][fired], rtol=1e-7)
    for a, b in zip(fast[1:], exact[1:]):
        assert torch.allclose(a.double(), b, rtol=1e-5, atol=1e-5 * b.abs().max().item())


@pytest.mark.parametrize("fast", [None, ttfs.dense])  # event-driven, or dense per field
@pytest.mark.parametrize(
    ("batch", "stride", "padding", "kernel"),
    [(3, 2, 1, 3), (2, 1, 2, 3), (0, 2, 1, 3), (3, 2, 2, 5), (2, 3, 0, 4)],
)
def test_the_convolution_matches_its_reference(fast, batch, stride, padding, kernel, conv_case):
    z, w = conv_case(batch, stride, kernel)

    def conv(layer):
        return lambda a, b: ttfs.conv2d(a, b, stride=stride, padding=padding, layer=layer)

    ref, got = _run(conv(ttfs.dense_torch), z, w, 4), _run(conv(fast), z, w, 4)
    assert torch.equal(torch.isfinite(ref[0]), torch.isfinite(got[0]))
    fired = torch.isfinite(ref[0])
    assert torch.allclose(ref[0][fired], got[0][fired], rtol=1e-12)
    for a, b in zip(ref[1:], got[1:]):
        assert torch.allclose(a, b, rtol=1e-10, atol=1e-10)
    if batch:
        assert 0 < fired.float().mean() < 1


def test_the_thread_count_changes_nothing_but_rounding(dense_case):
    if numba.config.NUMBA_NUM_THREADS < 2:  # NUMBA_NUM_THREADS=1 caps set_num_threads at 1:
        # compare in a process allowed two threads (numba runs more threads than cores)
        env = {**os.environ, "NUMBA_NUM_THREADS": "2"}
        test = f"{__file__}::test_the_thread_count_changes_nothing_but_rounding"
        done = subprocess.run([sys.executable, "-m", "pytest", "-q", test], env=env)
        assert done.returncode == 0
        return
    z, w = dense_case(50, 40, 16, 5)
    previous = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = _run(ttfs.dense, z, w, 5)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        many = _run(ttfs.dense, z, w, 5)
    finally:
        numba.set_num_threads(previous)
    assert torch.equal(one[0], many[0]) and torch.equal(one[1], many[1])
    assert torch.allclose(one[2], many[2], rtol=1e-12)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_spikes_are_put_in_time_order_ties_by_index(dtype):
    """ttfs_kernels.time_order (a radix sort of the bit patterns) against numpy's stable sort:
    ties, zeros of both signs, silent inputs, values spanning many binades."""
    rng = np.random.default_rng(7)
    flat = np.exp(rng.uniform(-20, 20, 5000)).astype(dtype)
    flat[rng.random(5000) < 0.2] = np.inf
    flat[:50] = flat[60]  # a tie
    flat[100:110] = 0.0
    flat[110:120] = -0.0
    flat[200:300] = np.round(flat[200:300] * 4) / 4
    expected = np.flatnonzero(np.isfinite(flat))
    expected = expected[np.argsort(flat[expected], kind="stable")]
    assert np.array_equal(ttfs_kernels.time_order(flat), expected)
    assert ttfs_kernels.time_order(np.full(3, np.inf, dtype=dtype)).size == 0
    assert ttfs_kernels.time_order(np.empty(0, dtype=dtype)).size == 0
