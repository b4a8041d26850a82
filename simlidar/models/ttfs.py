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

Two implementations compute the same spikes and gradients, and :func:`dense` and
:func:`conv2d` pick one by the tensors' device: on the CPU the compiled kernels of
:mod:`simlidar.models.ttfs_kernels` (each row's inputs walked in time order until every neuron
has fired; docs/performance.md), on any other device the torch form (:func:`dense_torch`:
tensor operations over every prefix of a chunk of rows, on the tensors' own device), which is
also the kernels' oracle in the tests. :func:`torch_form` makes the CPU run the torch form.
Both sum in float64 whatever the inputs' dtype, so their spikes agree to float64 rounding
(tests/models/test_ttfs_torch.py); ``torch_form(sums=torch.float32)`` sums in float32, only to
measure what that would change (benchmark/ttfs_float32.py).
"""

import contextlib
import contextvars

import torch
import torch.nn.functional as F

MIN_EXCESS = 1e-4


NEAR_FIRST, FAR_FIRST = "near_first", "far_first"  # which delay spikes first
DIRECTIONS = (NEAR_FIRST, FAR_FIRST)
AS_VALUE, FARTHEST, NO_SPIKE = "as_value", "farthest", "no_spike"  # a missing return
OWN_CHANNEL = "own_channel"  # ... or a spike of an input channel of its own (input_channels)
MISSING = (AS_VALUE, FARTHEST, NO_SPIKE, OWN_CHANNEL)


def input_channels(missing: str) -> int:
    """How many input channels :func:`encode` makes of each channel of the delays: 2 where a
    missing return has a channel of its own, else 1."""
    return 2 if missing == OWN_CHANNEL else 1


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
      "own_channel" no spike, and a spike of a second channel at the window's end (d = 1.0:
                    t = scale near-first, t = 0 far-first) where a return is missing, none where
                    one came back: the sensor knows a pulse found nothing once its window has
                    closed, and the network is told so as an input spike of its own. The
                    returns' channels come first, then the missing returns' (axis 1 of
                    (B, C, H, W) or (N, P) delays, the only axis of 1-D ones): twice the inputs

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
        spike = torch.ones_like(absent) if missing == FARTHEST else ~absent
        delays = torch.where(absent, 1.0, delays) if missing == FARTHEST else delays
    if direction == FAR_FIRST:
        delays = 1.0 - delays
    z = torch.where(spike, torch.exp(scale * torch.where(spike, delays, 0.0)), torch.inf)
    if missing != OWN_CHANNEL:
        return z
    end = torch.exp(z.new_tensor(scale if direction == NEAR_FIRST else 0.0))  # z's device, dtype
    told = torch.where(absent, end, z.new_tensor(torch.inf))
    return torch.cat([z, told], dim=1 if z.dim() > 1 else 0)


# Elements of one (rows, inputs, outputs) prefix tensor the torch form holds at a time: on a
# CPU a few MB, so that its dozen passes over it stay in cache (docs/performance.md); elsewhere
# a bound on memory (512 MB a tensor in float64), one chunk for the paper's networks' batches.
CHUNK_ELEMENTS = {"cpu": 1 << 19}
CHUNK_ELEMENTS_ELSEWHERE = 1 << 26

_TORCH_FORM = contextvars.ContextVar("simlidar_ttfs_torch_form", default=False)
# the dtype the torch form sums in: float64, as the kernels; float32 only in a study of what
# float32 sums would change (benchmark/ttfs_float32.py)
_SUM_DTYPE = contextvars.ContextVar("simlidar_ttfs_sum_dtype", default=torch.float64)
SUM_DTYPES = (torch.float64, torch.float32)


@contextlib.contextmanager
def torch_form(enabled: bool = True, sums: torch.dtype = torch.float64):
    """Within this block :func:`dense` and :func:`conv2d` run the torch form on CPU tensors too
    (``enabled=False``: the compiled kernels again); for tests and benchmarks. Which form a
    layer ran is chosen at its forward pass: its backward follows it.

    sums : the dtype the torch form sums in (on every device) within the block: float64, as
        the kernels and the torch form always do elsewhere, or float32 (what float32 sums
        would change: benchmark/ttfs_float32.py)
    """
    if sums not in SUM_DTYPES:
        raise ValueError(f"sums={sums}: expected one of {SUM_DTYPES}")
    token, dtype = _TORCH_FORM.set(enabled), _SUM_DTYPE.set(sums)
    try:
        yield
    finally:
        _TORCH_FORM.reset(token)
        _SUM_DTYPE.reset(dtype)


def first_spikes(z: torch.Tensor, budget: int) -> torch.Tensor:
    """Input spikes ``z`` (B, ...) (z domain, inf = none) with only each sample's first
    ``budget`` spikes kept (every spike at the budget-th's time too: they arrive together, as
    in :func:`simlidar.bench.bound.arrived`); the later ones become no spike. A gate that
    closes the input after ``budget`` spikes, so a network behind it decides on at most that
    many (docs/snn.md, "Deciding as early as the data allow")."""
    flat = z.flatten(1)
    nth = torch.kthvalue(flat, min(budget, flat.shape[1]), dim=1).values  # inf: fewer spikes
    return torch.where(flat <= nth[:, None], flat, torch.inf).view_as(z)


def first_columns(z: torch.Tensor, columns: int) -> torch.Tensor:
    """Input spikes ``z`` (B, ..., W) (z domain) with only the first ``columns`` columns of the
    last axis kept; the later ones become no spike. Under scan timing the columns are the
    sweep's firings in order, so a network behind this gate has what the sensor delivered by
    the end of its ``columns``-th firing (:class:`simlidar.models.networks.SpikingNet`)."""
    keep = torch.arange(z.shape[-1], device=z.device) < columns
    return torch.where(keep, z, torch.inf)


def uses_kernels(*tensors: torch.Tensor) -> bool:
    """True where :func:`dense` and :func:`conv2d` run the compiled kernels: every tensor on
    the CPU, outside :func:`torch_form`."""
    return all(t.device.type == "cpu" for t in tensors) and not _TORCH_FORM.get()


def _row_chunks(rows: int, per_row: int, device: torch.device) -> list[slice]:
    """Slices of at most ``CHUNK_ELEMENTS`` / ``per_row`` rows (at least one) covering ``rows``."""
    budget = CHUNK_ELEMENTS.get(device.type, CHUNK_ELEMENTS_ELSEWHERE)
    step = max(1, budget // max(per_row, 1))
    return [slice(i, min(rows, i + step)) for i in range(0, rows, step)]


def _scratch(parts: list[slice], per_row: int, like: torch.Tensor, *dtypes: torch.dtype):
    """One flat buffer of each dtype, large enough for the largest chunk's (r, ..., ...) tensor:
    allocated once a call and reused by every chunk (on a CPU a fresh multi-MB tensor a pass
    costs more than the pass: its pages are faulted in and zeroed, measured 3x on a mul)."""
    size = max((p.stop - p.start for p in parts), default=0) * per_row
    return [torch.empty(size, dtype=dtype, device=like.device) for dtype in dtypes]


def _first_spikes(z: torch.Tensor, w: torch.Tensor):
    """Forward of the torch form. z (R, N) float64 with inf = silent, w (N, M) float64.

    returns z_out (R, M) (inf: silent), z_last (R, M), the time of the causal set's last input
    (-inf: silent; the set is the inputs at or before it) and excess (R, M), sum_C w - 1 (1:
    silent).

    Chunk by chunk of rows: sort each row once, gather the weights in time order (r, K, M) (K
    the chunk's largest spike count: silent inputs sort last and no firing prefix reaches
    them), cumulative sums of w and w z over the prefixes, and each neuron's first valid
    prefix. Silent inputs' weights are not masked: a prefix that reaches one is never valid
    (its time is inf), so what they add to the sums is never used.
    """
    rows, n_in = z.shape
    n_out = w.shape[1]
    z_out = z.new_full((rows, n_out), torch.inf)
    z_last = z.new_full((rows, n_out), -torch.inf)
    excess = z.new_ones((rows, n_out))
    parts = _row_chunks(rows, n_in * n_out, z.device)
    bufs = _scratch(parts, n_in * n_out, z, z.dtype, z.dtype, torch.bool, torch.bool)
    for part in parts:
        spiking = int(torch.isfinite(z[part]).sum(dim=1).max())  # one host sync a chunk
        if spiking == 0:
            continue  # every row of the chunk silent: so are its outputs
        zs, order = torch.sort(z[part], dim=1, stable=True)  # ties: the same order every run
        zs, order = zs[:, :spiking], order[:, :spiking]  # (r, K)
        shape = (*zs.shape, n_out)  # (r, K, M)
        ws, cand, valid, test = (b[: zs.numel() * n_out].view(shape) for b in bufs)
        torch.index_select(w, 0, order.flatten(), out=ws.view(-1, n_out))
        zs0 = torch.where(torch.isfinite(zs), zs, 0.0)
        torch.mul(ws, zs0[..., None], out=cand)
        ws[:, 0] -= 1.0  # so that the cumulative sums are sum w - 1
        ex = ws.cumsum_(dim=1)  # the excess of every prefix
        cand.cumsum_(dim=1).div_(ex)  # candidate z_out
        nxt = torch.cat([zs[:, 1:], torch.full_like(zs[:, :1], torch.inf)], dim=1)
        torch.gt(ex, MIN_EXCESS, out=valid)
        valid &= torch.ge(cand, zs[..., None], out=test)  # not before the prefix's last input
        valid &= torch.lt(cand, nxt[..., None], out=test)  # strictly before the next input
        fired, last = valid.view(torch.uint8).max(dim=1)  # the first valid prefix (r, M)
        fired = fired.bool()
        pick = last[:, None, :]
        z_out[part] = torch.where(fired, cand.gather(1, pick).squeeze(1), torch.inf)
        z_last[part] = torch.where(fired, zs.gather(1, last), -torch.inf)
        excess[part] = torch.where(fired, ex.gather(1, pick).squeeze(1), 1.0)
    return z_out, z_last, excess


def _spike_gradients(z, w, z_out, z_last, excess, grad_out, need_z: bool, need_w: bool):
    """Backward of the torch form, all float64 (shapes as :func:`_first_spikes`): the input
    gradient (R, N) and the weight gradient (N, M) (None where not needed). An input is in a
    neuron's causal set iff its time is at or before ``z_last`` (a firing prefix never ends
    inside a group of equal times, so this is the prefix of the forward pass)."""
    rows, n_in = z.shape
    n_out = w.shape[1]
    fired = torch.isfinite(z_out)
    g = torch.where(fired, grad_out, 0.0).div_(excess)  # (R, M); excess is 1 where silent
    z0 = torch.where(torch.isfinite(z), z, 0.0)
    zo = torch.where(fired, z_out, 0.0)
    grad_z = torch.zeros_like(z) if need_z else None
    grad_w = torch.zeros_like(w) if need_w else None
    parts = _row_chunks(rows, n_in * n_out, z.device)
    bufs = _scratch(parts, n_in * n_out, z, torch.bool, z.dtype, z.dtype)
    for part in parts:
        shape = (part.stop - part.start, n_in, n_out)
        causal, coeff, tmp = (b[: shape[0] * n_in * n_out].view(shape) for b in bufs)
        torch.le(z[part, :, None], z_last[part, None, :], out=causal)  # silent: none
        coeff.copy_(causal).mul_(g[part, None, :])
        if need_z:
            grad_z[part] = torch.mul(coeff, w, out=tmp).sum(dim=2)
        if need_w:
            torch.sub(z0[part, :, None], zo[part, None, :], out=tmp)
            grad_w += tmp.mul_(coeff).sum(dim=0)
    return grad_z, grad_w


class _DenseTTFSTorch(torch.autograd.Function):
    """The dense layer as tensor operations on the tensors' own device, in float64 whatever
    their dtype, as the kernels sum (:func:`_first_spikes`, :func:`_spike_gradients`)."""

    @staticmethod
    def forward(ctx, z, w):
        dtype = torch.promote_types(z.dtype, w.dtype)  # the kernels' output dtype
        sums = _SUM_DTYPE.get()  # float64 but in a study of float32 sums
        z_out, z_last, excess = _first_spikes(z.detach().to(sums), w.detach().to(sums))
        ctx.save_for_backward(z, w, z_out, z_last, excess)
        return z_out.to(dtype)

    @staticmethod
    def backward(ctx, grad_out):
        z, w, z_out, z_last, excess = ctx.saved_tensors
        sums = z_out.dtype  # the forward pass's
        grad_z, grad_w = _spike_gradients(
            z.detach().to(sums),
            w.detach().to(sums),
            z_out,
            z_last,
            excess,
            grad_out.to(sums),
            *ctx.needs_input_grad,
        )
        return (
            grad_z.to(z.dtype) if grad_z is not None else None,
            grad_w.to(w.dtype) if grad_w is not None else None,
        )


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

    On CPU tensors the compiled kernels run (:mod:`simlidar.models.ttfs_kernels`), on any other
    device (or within :func:`torch_form`) the torch form, :func:`dense_torch`.
    """
    if uses_kernels(z, w):
        return _DenseTTFS.apply(z, w)
    return _DenseTTFSTorch.apply(z, w)


class _ConvTTFS(torch.autograd.Function):
    """The convolutional layer by the event-driven kernels (:mod:`simlidar.models.ttfs_kernels`:
    each sample's spikes sorted once, delivered to every receptive field that holds them)."""

    @staticmethod
    def forward(ctx, z, w, stride, padding):
        """The layer's output spikes by :func:`simlidar.models.ttfs_kernels.conv_forward`, in
        the wider of z's and w's dtypes.

        ctx : the autograd context, which keeps z, w and the kernel's z_out, z_last and excess
            (``save_for_backward``) and ``(stride, padding)`` (``ctx.geometry``) for backward
        z : (B, C_in, H, W) input spikes in the z domain, inf = no spike
        w : (C_out, C_in, k, k) weights
        stride, padding : the step between receptive fields and the "no spike" border added on
            each side of H and W, in pixels
        returns : (B, C_out, H_out, W_out) output spikes in the z domain, inf = no spike
        """
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


def dense_torch(z: torch.Tensor, w: torch.Tensor) -> torch.Tensor:
    """:func:`dense` as tensor operations on the tensors' own device, whatever it is: each row
    sorted once, cumulative sums over its prefixes, each neuron's first valid prefix picked
    (:func:`_first_spikes`); float64 inside, as the kernels. What :func:`dense` runs off the CPU,
    and the kernels' oracle in the tests."""
    return _DenseTTFSTorch.apply(z, w)


def conv2d(
    z: torch.Tensor, w: torch.Tensor, stride: int = 1, padding: int = 0, layer=None
) -> torch.Tensor:
    """First output spikes of a 2D convolutional TTFS layer (each output is a dense TTFS neuron
    over its receptive field, weights shared across positions).

    z : (B, C_in, H, W) input spikes in the z domain, inf = no spike
    w : (C_out, C_in, k, k) weights
    stride, padding : the step between receptive fields and the border added on each side of H
        and W, in pixels
    layer : None (the event-driven kernels on CPU tensors, :func:`dense_torch` on every
        receptive field elsewhere or within :func:`torch_form`), or a dense layer run on every
        receptive field
    returns : (B, C_out, H_out, W_out); padding adds "no spike" (inf), never an early spike
    """
    if layer is None:
        if uses_kernels(z, w):
            return _ConvTTFS.apply(z, w, stride, padding)
        layer = dense_torch
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
    z_in: torch.Tensor, w: torch.Tensor, target: torch.Tensor, margin: float
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


def early_term(z_out: torch.Tensor, target: torch.Tensor, form: str, beta: float, margin: float):
    """The early-decision loss term of ``form``
    (:data:`simlidar.models.training_config.EARLY_FORMS`) on output spikes ``z_out`` (B, M) (z
    domain, inf: none) and labels ``target`` (B,):

    linear    mean spike time t = ln z of the correct output (:func:`target_time`)
    exp       mean exp(t / beta) of the correct output (Goeltz et al. 2021, their alpha being
              the term's weight): it grows fast for late outliers and barely moves early ones
    relative  S4NN's relative targets (Kheradpisheh & Masquelier 2020) as a squared hinge: the
              correct output's target is the earliest output's time t_min (detached), every
              other output's target is no earlier than t_min + margin; the mean over samples of
              (t_correct - t_min)^2 + sum over the others of max(0, t_min + margin - t_j)^2
    Samples whose correct output is silent add nothing (the firing penalty moves those)."""
    if form == "linear":
        return target_time(z_out, target)
    z = z_out.gather(1, target[:, None]).squeeze(1)
    fired = torch.isfinite(z)
    if not fired.any():
        return z_out.new_zeros(())
    if form == "exp":
        return torch.exp(torch.log(z[fired]) / beta).mean()
    t = torch.log(z_out[fired])  # (F, M), inf for silent outputs
    y = target[fired]
    t_min = t.detach().amin(1, keepdim=True)
    correct = t.gather(1, y[:, None]).squeeze(1) - t_min.squeeze(1)
    others = torch.relu(t_min + margin - torch.where(torch.isfinite(t), t, t_min + margin))
    others = others.scatter(1, y[:, None], 0.0)
    return (correct**2 + (others**2).sum(1)).mean()


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
