"""The time-to-first-spike layers against the neuron's differential equation and gradcheck."""

import numpy as np
import pytest
import torch

from simlidar.models import ttfs


def integrate(t_in: np.ndarray, w: np.ndarray, dt: float = 2e-4, horizon: float = 8.0):
    """First threshold crossing of dV/dt = I, dI/dt = -I, I += w_i at t_i (forward Euler).

    t_in : (B, N) input spike times (inf = none); w : (N, M)
    returns : (B, M) first spike times, inf where V stays below 1 until the horizon
    """
    batch, (_, m) = t_in.shape[0], w.shape
    current = np.zeros((batch, m))
    potential = np.zeros((batch, m))
    fired = np.full((batch, m), np.inf)
    steps = int(horizon / dt)
    arrival = np.where(np.isfinite(t_in), np.ceil(t_in / dt), -1).astype(np.int64)
    for k in range(steps):
        arriving = arrival == k  # (B, N)
        if arriving.any():
            current += arriving.astype(float) @ w
        potential += dt * current
        current -= dt * current
        crossed = (potential >= 1.0) & ~np.isfinite(fired)
        fired[crossed] = (k + 1) * dt
    return fired


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_closed_form_matches_the_differential_equation(seed):
    rng = np.random.default_rng(seed)
    t_in = rng.uniform(0.0, 2.0, size=(6, 8))
    t_in[rng.random(t_in.shape) < 0.2] = np.inf  # some inputs never spike
    w = rng.uniform(-0.3, 0.7, size=(8, 5))
    w[:, 0] = 0.05  # a neuron whose weights never reach the threshold: silent
    z = torch.from_numpy(np.exp(t_in))
    closed = np.log(ttfs.dense(z, torch.from_numpy(w)).numpy())
    numeric = integrate(t_in, w)
    assert np.isinf(closed[:, 0]).all() and np.isinf(numeric[:, 0]).all()
    both = np.isfinite(closed) & np.isfinite(numeric)
    assert (np.isfinite(closed) == np.isfinite(numeric)).all()
    assert both.sum() > 10
    np.testing.assert_allclose(closed[both], numeric[both], atol=3e-3)


def test_a_single_input_by_hand():
    # one input at t = 0 with weight 2: V(t) = 2 (1 - e^-t) = 1 at t = ln 2, z = 2
    z = ttfs.dense(torch.tensor([[1.0]]), torch.tensor([[2.0]]))
    assert z.item() == pytest.approx(2.0)
    # weight 1 exactly: the potential only approaches the threshold, no spike
    assert torch.isinf(ttfs.dense(torch.tensor([[1.0]]), torch.tensor([[1.0]]))).all()


def test_an_output_spike_before_a_late_input_ignores_it():
    # inputs at t = 0 (w = 2) and t = 5 (w = -10): the neuron fires at ln 2, before the second
    z = torch.tensor([[1.0, np.exp(5.0)]])
    w = torch.tensor([[2.0], [-10.0]])
    assert ttfs.dense(z, w).item() == pytest.approx(2.0)


def _finite(f):
    def wrapped(*args):
        out = f(*args)
        return torch.where(torch.isfinite(out), out, 0.0)

    return wrapped


def test_gradcheck_dense():
    g = torch.Generator().manual_seed(3)
    z = torch.exp(torch.rand(5, 7, generator=g, dtype=torch.float64) * 2)
    z[1, 3] = torch.inf
    z.requires_grad_()
    w = (torch.rand(7, 4, generator=g, dtype=torch.float64) * 0.8).requires_grad_()
    assert torch.autograd.gradcheck(_finite(ttfs.dense), (z, w), eps=1e-6, atol=1e-5)


def test_gradcheck_conv():
    g = torch.Generator().manual_seed(4)
    z = torch.exp(torch.rand(2, 2, 5, 5, generator=g, dtype=torch.float64) * 2)
    z.requires_grad_()
    w = (torch.rand(3, 2, 3, 3, generator=g, dtype=torch.float64) * 0.5).requires_grad_()
    conv = _finite(lambda a, b: ttfs.conv2d(a, b, stride=2, padding=1))
    assert torch.autograd.gradcheck(conv, (z, w), eps=1e-6, atol=1e-5)


def test_silent_neurons_carry_no_nan_or_inf_into_gradients():
    z = torch.tensor([[1.0, torch.inf, 3.0]], requires_grad=True)
    w = torch.tensor([[0.1, 2.0], [5.0, 1.0], [0.2, 0.5]], requires_grad=True)
    out = ttfs.dense(z, w)
    assert torch.isinf(out[0, 0]) and torch.isfinite(out[0, 1])
    loss = torch.nn.functional.cross_entropy(ttfs.output_logits(out), torch.tensor([0]))
    loss.backward()
    assert torch.isfinite(z.grad).all() and torch.isfinite(w.grad).all()
    assert z.grad[0, 1] == 0  # a silent input gets no gradient


def test_convolution_pads_with_no_spike():
    # a single early input in the corner; padding must not act like an extra early spike
    z = torch.full((1, 1, 3, 3), torch.inf)
    z[0, 0, 0, 0] = 1.0
    w = torch.full((1, 1, 3, 3), 2.0)
    out = ttfs.conv2d(z, w, padding=1)
    assert torch.isfinite(out).sum() == 4  # the 4 windows that contain the corner input
    assert torch.allclose(out[torch.isfinite(out)], torch.tensor(2.0))


def test_encoding_and_prediction():
    delays = torch.tensor([[0.0, 0.5, 1.0]])
    z = ttfs.encode(delays, scale=2.0)
    assert torch.allclose(z[0, :2], torch.tensor([1.0, np.e])) and torch.isinf(z[0, 2])
    out = torch.tensor([[3.0, 2.0, torch.inf], [torch.inf, torch.inf, torch.inf]])
    assert ttfs.predict(out).tolist() == [1, -1]  # silence is no answer, never class 0


def test_target_fire_penalty_pushes_a_silent_correct_output_to_fire():
    # sample 0: inputs 0 and 1 spiked; sample 1: only input 2
    z = torch.tensor([[1.0, 2.0, torch.inf], [torch.inf, torch.inf, 1.5]])
    w = torch.tensor([[0.3, 2.0], [0.4, 0.0], [3.0, 0.2]], requires_grad=True)
    target = torch.tensor([0, 1])
    out = ttfs.dense(z, w)
    assert torch.isinf(out[0, 0]) and torch.isinf(out[1, 1])  # both correct outputs silent
    penalty = ttfs.target_fire_penalty(z, w, target, margin=0.1)
    # sample 0: 1.1 - (0.3 + 0.4) = 0.4; sample 1: 1.1 - 0.2 = 0.9
    assert penalty.item() == pytest.approx((0.4 + 0.9) / 2)
    penalty.backward()
    expected = torch.zeros(3, 2)
    expected[0, 0] = expected[1, 0] = expected[2, 1] = -0.5  # only spiked inputs, target column
    assert torch.equal(w.grad, expected)
    with torch.no_grad():  # a descent step along it makes both correct outputs fire
        w -= 2.0 * w.grad
    assert torch.isfinite(ttfs.dense(z, w)[[0, 1], [0, 1]]).all()
    firing = torch.tensor([[1.0, 2.0, torch.inf]])
    assert ttfs.target_fire_penalty(firing, torch.full((3, 2), 1.0), torch.tensor([0]), 0.1) == 0


def test_target_time_averages_the_correct_outputs_that_fire():
    z = torch.tensor(
        [[torch.e, 1.0], [torch.inf, 2.0], [torch.e**3, torch.inf]], requires_grad=True
    )
    t = ttfs.target_time(z, torch.tensor([0, 0, 0]))
    assert t.item() == pytest.approx((1.0 + 3.0) / 2)  # the silent second sample is left out
    t.backward()
    assert torch.isfinite(z.grad).all() and z.grad[1].abs().sum() == 0
    assert z.grad[0, 0] == pytest.approx(0.5 / torch.e)  # d(ln z / 2)/dz
    silent = torch.full((2, 2), torch.inf)
    assert ttfs.target_time(silent, torch.tensor([0, 1])).item() == 0.0


def test_the_early_terms_by_hand():
    """Spike times t = ln z: sample 0 correct (class 0) at 1 before class 1 at 1.2; sample 1
    correct (class 1) at 2 after class 0 at 0.5, class 2 silent; sample 2's correct is silent."""
    e = torch.e
    z = torch.tensor(
        [[e, e**1.2, e**3], [e**0.5, e**2, torch.inf], [1.0, 1.0, torch.inf]],
        dtype=torch.float64,
        requires_grad=True,
    )
    y = torch.tensor([0, 1, 2])
    linear = ttfs.early_term(z, y, "linear", 1.0, 0.5)
    assert linear.item() == ttfs.target_time(z, y).item() == pytest.approx((1 + 2) / 2)
    exp = ttfs.early_term(z, y, "exp", 2.0, 0.5)
    assert exp.item() == pytest.approx((e**0.5 + e**1.0) / 2)  # exp(t / 2)
    relative = ttfs.early_term(z, y, "relative", 1.0, 0.5)
    # sample 0: correct is the earliest (0); class 1 at 1.2 is within 1 + 0.5: (0.3)^2; class 2
    # at 3 is past it. Sample 1: correct 1.5 after the earliest: 1.5^2; class 0 is t_min
    # itself, 0.5 - 0 short of t_min + 0.5: 0.5^2; silent class 2: nothing
    assert relative.item() == pytest.approx((0.3**2 + 1.5**2 + 0.5**2) / 2)
    relative.backward()
    assert torch.isfinite(z.grad).all() and z.grad[2].abs().sum() == 0
    assert z.grad[1, 1] > 0 and z.grad[0, 1] < 0  # correct later: pulled in; a rival: pushed out
    silent = torch.full((2, 2), torch.inf)
    for form in ("exp", "relative"):
        assert ttfs.early_term(silent, torch.tensor([0, 1]), form, 1.0, 0.5).item() == 0.0


def test_a_row_gets_the_same_spikes_and_gradients_alone_and_in_a_batch():
    # rows with 0, 2, 5 and 8 input spikes: the batch keeps only the first 8 of the time order
    g = torch.Generator().manual_seed(3)
    z = torch.exp(3 * torch.rand(4, 12, generator=g, dtype=torch.float64))
    for row, spikes in enumerate((0, 2, 5, 8)):
        z[row, spikes:] = torch.inf
    z = z[:, torch.randperm(12, generator=g)]  # silent inputs anywhere, not only at the end
    w = torch.rand(12, 6, generator=g, dtype=torch.float64) * 0.6

    def run(rows):
        zz, ww = z[rows].clone().requires_grad_(), w.clone().requires_grad_()
        out = ttfs.dense(zz, ww)
        torch.where(torch.isfinite(out), out, 0.0).sum().backward()
        return out.detach(), zz.grad, ww.grad

    batch = run(slice(None))
    alone = [run(slice(r, r + 1)) for r in range(4)]
    assert torch.isfinite(batch[0]).any() and torch.isinf(batch[0][0]).all()
    for r in range(4):
        assert torch.equal(batch[0][r], alone[r][0][0]) and torch.equal(batch[1][r], alone[r][1][0])
    assert torch.allclose(batch[2], sum(a[2] for a in alone))
