"""Time-to-first-spike layers (Mostafa 2018) as pure functions on whole batches.

Neuron model: non-leaky integrate-and-fire with exponentially decaying synaptic current
(time constant 1). Input spike i at time t_i with weight w_i adds w_i (1 - exp(-(t - t_i)))
to the membrane potential for t > t_i; the neuron fires once, when the potential reaches the
threshold 1. In z = exp(t) the first spike time has the closed form

    z_out = sum_{i in C} w_i z_i / (sum_{i in C} w_i - 1)

where C is the set of inputs that arrive before the output spike: the shortest time-ordered
prefix for which ``sum_C w_i - 1 > MIN_EXCESS``, ``z_out >= z_last(C)`` and ``z_out`` comes
before the next input (``z_out < z_next``). A neuron with no such prefix never fires.

Representation: spike times travel in the z domain; ``z = inf`` means "no spike". No
arithmetic ever runs on an infinite value: silent inputs only enter comparisons (their z is
replaced by 0 in every sum, and no firing prefix reaches them), silent outputs get zero
gradient. ``exp`` is only taken of the bounded input times (see :func:`encode`).

Near-zero denominators: a prefix whose weight excess ``sum_C w_i - 1`` is not above
``MIN_EXCESS`` (1e-4) is not a firing prefix. The neuron's potential would approach the
threshold only asymptotically (firing after ln(sum w z / excess) time units or never), and
the division would amplify rounding error without bound.

Gradients (hand-written backward, checked by ``torch.autograd.gradcheck``), for i in C:
``dz_out/dz_i = w_i / (sum_C w - 1)`` and ``dz_out/dw_i = (z_i - z_out) / (sum_C w - 1)``;
zero for inputs outside C and for neurons that do not fire.

Two implementations compute the same spikes and gradients: :func:`dense` runs the compiled
kernels of :mod:`simlidar.models.ttfs_kernels` (each row's inputs walked in time order until
every neuron has fired; docs/performance.md), and :func:`dense_reference`, the batched tensor
form below, is their oracle in the tests.
"""

import torch
import torch.nn.functional as F

MIN_EXCESS = 1e-4


NEAR_FIRST, FAR_FIRST = "near_first", "far_first"  # which delay spikes first
DIRECTIONS = (NEAR_FIRST, FAR_FIRST)
AS_VALUE, FARTHEST, NO_SPIKE = "as_value", "farthest", "no_spike"  # a missing return
MISSING = (AS_VALUE, FARTHEST, NO_SPIKE)


def encode(
    delays: torch.Tensor,
    scale: float,
    no_return: float = 1.0,
    direction: str = NEAR_FIRST,
    missing: str = AS_VALUE,
) -> torch.Tensor:
    """Normalised delays in [0, 1] -> input spikes in the z domain.

    direction : which delay spikes first
      "near_first"  t = scale * d: a near return first (simlidar's encoding, the default)
      "far_first"   t = scale * (1 - d): a larger value first (the authors' public code,
                    t = 3 (1 - x))
    missing : what a missing return becomes; a delay is a missing return when it is at or
      above ``no_return`` or at the end of the window (1.0); one the data writes as 0.0 plus
      noise (the ``paper`` profile) cannot be told from a near return and keeps its value
      "as_value"    the data's rule, as before: a delay at or above ``no_return`` is no spike,
                    every other delay spikes at its value (the default)
      "farthest"    spikes as the farthest value, d = 1.0: last near-first, at t = 0 far-first
                    (the authors' KITTI range maps)
      "no_spike"    no spike

    z = exp(t) lies in [1, exp(scale)]; no spike is z = inf. With the defaults and
    ``no_return = inf`` (the paper profile) every pixel is a spike at t = scale * d.
    """
    if direction not in DIRECTIONS or missing not in MISSING:
        raise ValueError(
            f"direction={direction!r}, missing={missing!r}: expected one of "
            f"{DIRECTIONS} and one of {MISSING}"
        )
    if missing == AS_VALUE:
        spike = delays < no_return
    else:
        absent = (delays >= no_return) | (delays >= 1.0)
        spike = ~absent if missing == NO_SPIKE else torch.ones_like(absent)
        delays = torch.where(absent, 1.0, delays) if missing == FARTHEST else delays
    if direction == FAR_FIRST:
        delays = 1.0 - delays
    return torch.where(spike, torch.exp(scale * torch.where(spike, delays, 0.0)), torch.inf)


def _first_spikes(z: torch.Tensor, w: torch.Tensor):
    """Forward of the dense layer. z (B, N) with inf = silent, w (N, M).

    returns z_out (B, M) (inf = silent), and what the backward needs: the time order of the
    inputs (B, K), K <= N (only the inputs that can be in a causal set), the index of the last
    input of the causal set (B, M) (-1 if silent) and its weight excess sum_C w - 1 (B, M)
    (1 if silent).

    Work is done in place on the (B, K, M) prefix tensors (the layer's cost). Silent inputs sort
    last and their weights are not masked: a prefix that reaches one is never valid (its
    ``zs`` is inf), so what they add to the sums is never used.
    """
    # silent inputs (inf) sort last; prefixes past the last spike of every row are never
    # valid, so only the first K of the order matter, K the batch's largest spike count
    spiking = int(torch.isfinite(z).sum(dim=1).max()) if z.shape[0] else 0
    order = torch.argsort(z, dim=1)[:, : max(spiking, 1)]  # (B, K)
    zs = torch.gather(z, 1, order)  # (B, K)
    zs0 = torch.where(torch.isfinite(zs), zs, 0.0)
    ws = w[order]  # (B, K, M)
    excess = torch.cumsum(ws, dim=1).sub_(1.0)  # sum of the first k+1 weights - 1
    cand = torch.cumsum(ws.mul_(zs0[..., None]), dim=1).div_(excess)  # candidate z_out
    nxt = torch.cat([zs[:, 1:], torch.full_like(zs[:, :1], torch.inf)], dim=1)  # (B, K)
    valid = excess > MIN_EXCESS
    valid &= cand >= zs[..., None]  # not before the prefix's last input (silent: never)
    valid &= cand < nxt[..., None]  # strictly before the next input
    last = torch.argmax(valid.view(torch.uint8), dim=1)  # first valid prefix (0 if none)
    pick = last[:, None, :]
    fired = torch.gather(valid, 1, pick).squeeze(1)  # (B, M)
    z_out = torch.where(fired, torch.gather(cand, 1, pick).squeeze(1), torch.inf)
    excess_at = torch.where(fired, torch.gather(excess, 1, pick).squeeze(1), 1.0)
    return z_out, order, torch.where(fired, last, -1), excess_at


class _DenseTTFSReference(torch.autograd.Function):
    @staticmethod
    def forward(ctx, z, w):
        z_out, order, last, excess = _first_spikes(z, w)
        ctx.save_for_backward(z, w, z_out, order, last, excess)
        return z_out

    @staticmethod
    def backward(ctx, grad_out):
        z, w, z_out, order, last, excess = ctx.saved_tensors
        fired = last >= 0
        g = torch.where(fired, grad_out, 0.0) / excess  # (B, M), excess is 1 when silent
        rank = torch.full(z.shape, z.shape[1], dtype=order.dtype, device=z.device).scatter_(
            1, order, torch.arange(order.shape[1], device=z.device).expand_as(order)
        )  # each input's place in time order; N for those left out (never causal)
        causal = rank[:, :, None] <= last[:, None, :]  # (B, N, M): input in C (none if silent)
        coeff = torch.where(causal, g[:, None, :], 0.0)
        grad_z = grad_w = None
        if ctx.needs_input_grad[0]:
            grad_z = (coeff * w).sum(dim=2)
        if ctx.needs_input_grad[1]:
            z0 = torch.where(torch.isfinite(z), z, 0.0)
            zo = torch.where(fired, z_out, 0.0)
            grad_w = coeff.mul_(z0[:, :, None] - zo[:, None, :]).sum(dim=0)
        return grad_z, grad_w


class _DenseTTFS(torch.autograd.Function):
    """The same layer by the compiled kernels (:mod:`simlidar.models.ttfs_kernels`)."""

    @staticmethod
    def forward(ctx, z, w):
        import numba

        from simlidar.models import ttfs_kernels

        dtype = torch.promote_types(z.dtype, w.dtype)  # as the reference's arithmetic would
        zn, wn = (t.detach().to(dtype).contiguous().numpy() for t in (z, w))
        threads = max(1, min(numba.get_num_threads(), z.shape[0]))
        z_out, order, last, excess = ttfs_kernels.forward(zn, wn, MIN_EXCESS, threads)
        ctx.save_for_backward(z, w, *map(torch.from_numpy, (z_out, order, last, excess)))
        return torch.from_numpy(z_out)

    @staticmethod
    def backward(ctx, grad_out):
        import numba

        from simlidar.models import ttfs_kernels

        z, w, z_out, order, last, excess = ctx.saved_tensors
        threads = max(1, min(numba.get_num_threads(), z.shape[1]))  # blocks of inputs
        dtype = z_out.dtype
        grad_z, grad_w = ttfs_kernels.backward(
            *(t.detach().to(dtype).contiguous().numpy() for t in (z, w, z_out)),
            *(t.numpy() for t in (order, last, excess)),
            grad_out.detach().to(dtype).contiguous().numpy(),
            threads,
        )
        return (
            torch.from_numpy(grad_z).to(z.dtype) if ctx.needs_input_grad[0] else None,
            torch.from_numpy(grad_w).to(w.dtype) if ctx.needs_input_grad[1] else None,
        )


def dense(z: torch.Tensor, w: torch.Tensor) -> torch.Tensor:
    """First output spikes of a dense TTFS layer.

    z : (B, N) input spikes in the z domain, inf = no spike
    w : (N, M) weights
    returns : (B, M) output spikes in the z domain, inf = no spike
    """
    return _DenseTTFS.apply(z, w)


class _ConvTTFS(torch.autograd.Function):
    """The convolutional layer by the event-driven kernels (:mod:`simlidar.models.ttfs_kernels`:
    each sample's spikes sorted once, delivered to every receptive field that holds them)."""

    @staticmethod
    def forward(ctx, z, w, stride, padding):
        from simlidar.models import ttfs_kernels

        dtype = torch.promote_types(z.dtype, w.dtype)
        zn = z.detach().to(dtype).contiguous().numpy()
        wt = w.detach().to(dtype).permute(1, 2, 3, 0).contiguous().numpy()  # output channel last
        k = w.shape[2]
        h_out = (z.shape[2] + 2 * padding - k) // stride + 1
        w_out = (z.shape[3] + 2 * padding - k) // stride + 1
        z_out, z_last, excess = ttfs_kernels.conv_forward(
            zn, wt, stride, padding, h_out, w_out, MIN_EXCESS
        )
        outs = tuple(map(torch.from_numpy, (z_out, z_last, excess)))
        ctx.save_for_backward(z, w, *outs)
        ctx.geometry = (stride, padding)
        return outs[0]

    @staticmethod
    def backward(ctx, grad_out):
        import numba

        from simlidar.models import ttfs_kernels

        z, w, z_out, z_last, excess = ctx.saved_tensors
        stride, padding = ctx.geometry
        dtype = z_out.dtype
        threads = max(1, min(numba.get_num_threads(), z.shape[0]))
        grad_z, grad_wt = ttfs_kernels.conv_backward(
            z.detach().to(dtype).contiguous().numpy(),
            w.detach().to(dtype).permute(1, 2, 3, 0).contiguous().numpy(),
            stride,
            padding,
            z_out.numpy(),
            z_last.numpy(),
            excess.numpy(),
            grad_out.detach().to(dtype).contiguous().numpy(),
            threads,
        )
        grad_w = torch.from_numpy(grad_wt).permute(3, 0, 1, 2).to(w.dtype).contiguous()
        return (
            torch.from_numpy(grad_z).to(z.dtype) if ctx.needs_input_grad[0] else None,
            grad_w if ctx.needs_input_grad[1] else None,
            None,
            None,
        )


def dense_reference(z: torch.Tensor, w: torch.Tensor) -> torch.Tensor:
    """:func:`dense` as batched tensor operations over every prefix of every row: the oracle
    of the compiled kernels (and of any faster form to come)."""
    return _DenseTTFSReference.apply(z, w)


def conv2d(
    z: torch.Tensor, w: torch.Tensor, stride: int = 1, padding: int = 0, layer=None
) -> torch.Tensor:
    """First output spikes of a 2D convolutional TTFS layer (each output is a dense TTFS neuron
    over its receptive field, weights shared across positions).

    z : (B, C_in, H, W) input spikes in the z domain, inf = no spike
    w : (C_out, C_in, k, k) weights
    returns : (B, C_out, H_out, W_out); padding adds "no spike" (inf), never an early spike
    layer : None (the event-driven kernels), or a dense layer run on every receptive field
        (e.g. :func:`dense_reference`, the oracle)
    """
    if layer is None:
        return _ConvTTFS.apply(z, w, stride, padding)
    batch, channels = z.shape[:2]
    c_out, _, k, _ = w.shape
    if padding:
        z = F.pad(z, (padding,) * 4, value=torch.inf)
    h_out = (z.shape[2] - k) // stride + 1
    w_out = (z.shape[3] - k) // stride + 1
    patches = F.unfold(z, k, stride=stride)  # (B, C_in k k, L); copies values, inf stays inf
    flat = patches.transpose(1, 2).reshape(-1, channels * k * k)
    out = layer(flat, w.reshape(c_out, -1).t())  # (B L, C_out)
    return (
        out.reshape(batch, h_out * w_out, c_out).transpose(1, 2).reshape(batch, c_out, h_out, w_out)
    )


def weight_sum_penalty(w: torch.Tensor) -> torch.Tensor:
    """mean_j max(0, 1 - sum_i w_ij): pushes every neuron's total input weight above the
    threshold so that it can fire (Mostafa 2018). w : (N, M) or (C_out, C_in, k, k)."""
    per_neuron = w.sum(dim=0) if w.dim() == 2 else w.flatten(1).sum(dim=1)
    return torch.relu(1.0 - per_neuron).mean()


def target_fire_penalty(
    z_in: torch.Tensor, w: torch.Tensor, target: torch.Tensor, margin: float = 0.1
) -> torch.Tensor:
    """mean_b max(0, 1 + margin - sum_{i spiked} w_{i, target_b}): keeps each sample's correct
    output neuron able to fire.

    A neuron fires eventually iff the weights of the inputs that spiked sum above the
    threshold 1 (its potential tends to that sum), so a silent correct output is pushed towards
    firing; without this a silent output gets no gradient and stays silent (not in the paper).
    z_in : (B, N) the layer's input spikes (inf = none), w : (N, M), target : (B,) in [0, M).
    """
    spiked = torch.isfinite(z_in).to(w.dtype)
    reach = (spiked @ w).gather(1, target[:, None])  # (B, 1)
    return torch.relu(1.0 + margin - reach).mean()


def target_time(z_out: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean spike time t = ln z of each sample's correct output neuron, over the samples where
    it fires (0 if it fires in none): a loss term that rewards deciding early (not in the
    paper). z_out : (B, M) output spikes, target : (B,)."""
    z = z_out.gather(1, target[:, None]).squeeze(1)
    fired = torch.isfinite(z)
    if not fired.any():
        return z_out.new_zeros(())
    return torch.log(z[fired]).mean()


def output_logits(z_out: torch.Tensor) -> torch.Tensor:
    """Logits -z for a softmax over the output neurons; a silent neuron gets a logit below
    every firing one (no gradient), so it can never win the softmax by being silent."""
    fired = torch.isfinite(z_out)
    finite = torch.where(fired, z_out, 0.0)
    floor = finite.detach().amax(dim=1, keepdim=True) + 10.0
    return -torch.where(fired, finite, floor)


def predict(z_out: torch.Tensor) -> torch.Tensor:
    """The first output neuron to fire; -1 where none fires (counted as wrong, never class 0)."""
    first = torch.argmin(z_out, dim=1)
    return torch.where(torch.isfinite(z_out).any(dim=1), first, -1)
