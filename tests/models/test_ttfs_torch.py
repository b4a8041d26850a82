"""The torch form of the TTFS layers (what ``ttfs.dense`` and ``ttfs.conv2d`` run off the CPU),
forced onto the CPU with ``ttfs.torch_form()``, against the compiled kernels.

Attack list:
* float32 inputs (the kernels sum in float64; a float32 torch form would lose digits near the
  threshold and silence neurons the kernels fire), float64 inputs and mixed dtypes: the same
  silent neurons, spikes and both gradients to float tolerance, in the inputs' dtypes;
* batches with silent inputs, an all-silent row, a tie of half a row, many ties, silent output
  neurons, and the empty batch; convolutions with padding ("no spike"), strides, an all-silent
  sample and a tie across fields;
* rows split into many chunks (a tiny chunk budget), chunks whose rows are all silent: the same
  results as one chunk;
* the dispatch: outside ``torch_form`` the CPU runs the kernels; inside it no kernel runs and no
  tensor goes through numpy (what a GPU tensor could not do), forward and backward; the flag is
  restored after an exception in the block;
* a whole tiny ``dense_snn`` trained a few SGD steps with either form ends with the same weights.
"""

import pytest
import torch
import torch.nn.functional as F

from simlidar.models import ttfs, ttfs_kernels
from simlidar.models.networks import dense_snn


def _run(layer, z, w, seed: int, torch_form: bool):
    """Outputs and the gradients of a random weighting of the firing outputs."""
    z, w = z.clone().requires_grad_(), w.clone().requires_grad_()
    with ttfs.torch_form(torch_form):
        out = layer(z, w)
        weights = torch.randn(out.shape, generator=torch.Generator().manual_seed(seed))
        (torch.where(torch.isfinite(out), out, 0.0) * weights.to(out.dtype)).sum().backward()
    return out.detach(), z.grad, w.grad


def _same(kernels, torch_form, rtol: float):
    """The same silent set and, elsewhere, the same spikes and gradients within ``rtol``."""
    for a, b in zip(kernels, torch_form):
        assert a.dtype == b.dtype and a.shape == b.shape
    assert torch.equal(torch.isfinite(kernels[0]), torch.isfinite(torch_form[0]))
    fired = torch.isfinite(kernels[0])
    assert torch.allclose(kernels[0][fired], torch_form[0][fired], rtol=rtol, atol=0)
    for a, b in zip(kernels[1:], torch_form[1:]):
        scale = b.abs().max().item() if b.numel() else 0.0
        assert torch.allclose(a, b, rtol=rtol, atol=rtol * scale)
    return fired


TOLERANCE = {torch.float64: 1e-10, torch.float32: 1e-5}


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
@pytest.mark.parametrize(("rows", "n_in", "n_out"), [(40, 30, 12), (60, 256, 400), (0, 10, 4)])
def test_the_dense_torch_form_equals_the_kernels(dtype, rows, n_in, n_out, dense_case):
    z, w = dense_case(rows, n_in, n_out, seed=rows, dtype=dtype)
    kernels = _run(ttfs.dense, z, w, 1, torch_form=False)
    torch_form = _run(ttfs.dense, z, w, 1, torch_form=True)
    fired = _same(kernels, torch_form, TOLERANCE[dtype])
    if rows:
        assert 0 < fired.float().mean() < 1  # both firing and silent neurons were compared


def test_float32_decisions_are_made_in_float64(dense_case):
    """Float32 60 x 256 -> 400 batches on which prefix sums run in float32 (``_first_spikes`` on
    float32 tensors) fire or silence a neuron otherwise than in float64 (one of 24,000, in some
    of the seeds): the torch form decides as float64 does, as the kernels do."""
    hard = 0
    for seed in range(8):
        z, w = dense_case(60, 256, 400, seed, torch.float32)
        in_float32 = torch.isfinite(ttfs._first_spikes(z, w)[0])
        in_float64 = torch.isfinite(ttfs._first_spikes(z.double(), w.double())[0])
        if torch.equal(in_float32, in_float64):
            continue
        hard += 1
        with ttfs.torch_form():
            out = ttfs.dense(z, w)
        assert out.dtype == torch.float32
        assert torch.equal(torch.isfinite(out), in_float64)
        assert torch.equal(torch.isfinite(ttfs.dense(z, w)), in_float64)  # the kernels'
    assert hard >= 1


def test_the_torch_form_sums_in_float32_only_when_asked(dense_case):
    """``torch_form(sums=torch.float32)`` (the study of benchmark/ttfs_float32.py) decides as
    float32 prefix sums do, on the batches where those differ from float64; outside the block
    the sums are float64 again, and another dtype is refused."""
    differed = 0
    for seed in range(8):
        z, w = dense_case(60, 256, 400, seed, torch.float32)
        in_float32 = torch.isfinite(ttfs._first_spikes(z, w)[0])
        with ttfs.torch_form(sums=torch.float32):
            out = ttfs.dense(z.double(), w.double())
        assert out.dtype == torch.float64 and torch.equal(torch.isfinite(out), in_float32)
        with ttfs.torch_form():
            again = ttfs.dense(z.double(), w.double())
        differed += not torch.equal(torch.isfinite(again), in_float32)
    assert differed >= 1
    with pytest.raises(ValueError, match="sums=torch.float16: expected one of"):
        with ttfs.torch_form(sums=torch.float16):
            pass


def test_mixed_dtypes_promote_as_the_kernels_do(dense_case):
    z, w = dense_case(20, 16, 8, 5, torch.float32)
    w = w.double()
    kernels = _run(ttfs.dense, z, w, 2, torch_form=False)
    torch_form = _run(ttfs.dense, z, w, 2, torch_form=True)
    assert torch_form[0].dtype == torch.float64
    assert torch_form[1].dtype == torch.float32 and torch_form[2].dtype == torch.float64
    _same(kernels, torch_form, 1e-6)


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
@pytest.mark.parametrize(
    ("batch", "stride", "padding", "kernel"),
    [(3, 2, 1, 3), (2, 1, 2, 3), (0, 2, 1, 3), (3, 2, 2, 5), (2, 3, 0, 4)],
)
def test_the_convolution_torch_form_equals_the_kernels(
    dtype, batch, stride, padding, kernel, conv_case
):
    z, w = conv_case(batch, stride, kernel)
    z, w = z.to(dtype), w.to(dtype)

    def conv(a, b):
        return ttfs.conv2d(a, b, stride=stride, padding=padding)

    fired = _same(
        _run(conv, z, w, 4, torch_form=False),
        _run(conv, z, w, 4, torch_form=True),
        TOLERANCE[dtype],
    )
    if batch:
        assert 0 < fired.float().mean() < 1


def test_many_chunks_give_what_one_chunk_gives(monkeypatch, dense_case):
    z, w = dense_case(40, 30, 12, 6)
    z[20:32] = torch.inf  # with 4 rows a chunk, whole chunks of silent rows
    one = _run(ttfs.dense, z, w, 3, torch_form=True)
    monkeypatch.setitem(ttfs.CHUNK_ELEMENTS, "cpu", 4 * 30 * 12)
    assert len(ttfs._row_chunks(40, 30 * 12, z.device)) == 10
    many = _run(ttfs.dense, z, w, 3, torch_form=True)
    _same(one, many, 1e-12)
    assert torch.isinf(many[0][20:32]).all() and (many[1][20:32] == 0).all()


def _refuse(*args, **kwargs):
    raise AssertionError("the torch form must not call the compiled kernels or numpy")


def test_inside_torch_form_no_kernel_runs_and_nothing_goes_through_numpy(monkeypatch, dense_case):
    z, w = dense_case(10, 12, 5, 7)
    zc = torch.exp(torch.rand(2, 2, 6, 6, dtype=torch.float64))
    wc = torch.rand(3, 2, 3, 3, dtype=torch.float64) * 0.5
    for name in ("forward", "backward", "conv_forward", "conv_backward"):
        monkeypatch.setattr(ttfs_kernels, name, _refuse)
    monkeypatch.setattr(torch.Tensor, "numpy", _refuse)
    monkeypatch.setattr(torch, "from_numpy", _refuse)
    dense = _run(ttfs.dense, z, w, 0, torch_form=True)
    conv = _run(lambda a, b: ttfs.conv2d(a, b, 2, 1), zc, wc, 0, torch_form=True)
    assert all(torch.isfinite(t).any() for t in (*dense, *conv))
    with pytest.raises(AssertionError, match="must not call"):  # outside it: the kernels
        ttfs.dense(z, w)


def test_outside_torch_form_the_cpu_runs_the_kernels(monkeypatch, dense_case):
    calls = []
    real = ttfs_kernels.forward

    def counted(*args):
        calls.append(args[0].shape)
        return real(*args)

    monkeypatch.setattr(ttfs_kernels, "forward", counted)
    z, w = dense_case(10, 12, 5, 8)
    ttfs.dense(z, w)
    with ttfs.torch_form():
        ttfs.dense(z, w)
        with ttfs.torch_form(False):  # nested: the kernels again
            ttfs.dense(z, w)
    assert calls == [(10, 12), (10, 12)]
    assert ttfs.uses_kernels(z, w) and not ttfs.uses_kernels(z, w.to("meta"))


def test_the_flag_is_restored_after_an_exception():
    z = torch.ones(1, 1)
    with pytest.raises(RuntimeError), ttfs.torch_form():
        assert not ttfs.uses_kernels(z)
        raise RuntimeError("inside")
    assert ttfs.uses_kernels(z)


def _train(torch_form: bool, dtype: torch.dtype, steps: int = 6):
    """A 16-12-4 ``dense_snn`` trained ``steps`` SGD steps: its weights and, per step, the
    fraction of output spikes that fired."""
    generator = torch.Generator().manual_seed(0)
    net = dense_snn((1, 4, 4), 4, torch.Generator().manual_seed(1), hidden=(12,), excess=0.5)
    net = net.to(dtype)
    optimizer = torch.optim.SGD(net.parameters(), lr=0.05)
    x = torch.rand(32, 1, 4, 4, generator=generator, dtype=dtype)
    x[torch.rand(x.shape, generator=generator) < 0.2] = 1.0  # no return: silent inputs
    y = torch.randint(0, 4, (32,), generator=generator)
    fired = []
    with ttfs.torch_form(torch_form):
        for _ in range(steps):
            out = net(x)
            fired.append(torch.isfinite(out).float().mean().item())
            loss = F.cross_entropy(ttfs.output_logits(out), y) + 10 * net.penalty()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
    return [layer.weight.detach().clone() for layer in net.layers], fired


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_a_spiking_network_trains_to_the_same_weights_with_either_form(dtype):
    """Both forms' spikes round the same float64 values and their gradients differ by float64
    rounding, but z-domain gradients are large (thousands here), so a float32 ulp in one step
    moves later steps by a few ulps more: float32 is held to 1e-4 of the largest weight."""
    kernels, fired = _train(False, dtype)
    torch_form, fired_torch = _train(True, dtype)
    assert fired == fired_torch and 0 < min(fired) and max(fired) < 1  # silent outputs too
    initial = dense_snn((1, 4, 4), 4, torch.Generator().manual_seed(1), hidden=(12,), excess=0.5)
    rtol = 1e-4 if dtype == torch.float32 else 1e-10
    for a, b, start in zip(kernels, torch_form, initial.layers):
        assert (a.double() - start.weight.double()).abs().max() > 1.0  # the steps moved them
        assert torch.allclose(a, b, rtol=0, atol=rtol * a.abs().max().item())
