"""Compiled (numba) kernels of the dense TTFS layer: the same first spikes and gradients as the
batched reference (:func:`simlidar.models.ttfs.dense_reference`), row by row.

The reference materialises every prefix of every row: (rows, inputs, outputs) cumulative sums,
whatever the prefix at which the neurons fire. These kernels sort a row's spiking inputs and
walk them in time order, keeping one running weight sum and one running weighted sum per output
neuron, and stop as soon as every neuron of the row has fired: the work is the prefix actually
used, not the whole row, and nothing larger than a row's outputs is held. The backward pass
walks each row's causal prefix again. Rows run in parallel (``prange``); each thread adds its
weight gradient into its own buffer (in the weights' dtype), summed at the end, so the result
does not depend on the thread count beyond float rounding. The convolutional layer has kernels
of its own (:func:`conv_forward`): each sample's spikes are sorted once and delivered to every
receptive field that holds them, as the sensor would deliver them.

Sums run in float64 whatever the inputs' dtype, prefix by prefix in time order: near the
threshold (``sum_C w - 1`` close to ``MIN_EXCESS``) a float32 sum loses most of its digits to the
subtraction, so float32 inputs get float64 decisions and spike times (rounded to float32 at the
end); in float64 a neuron's causal set is the reference's. Ties do not matter: a firing prefix
never ends inside a group of equal input times, so the order within a tie changes nothing.

The backward kernels may reassociate their sums (``fastmath={"reassoc"}``, nothing else): the
input gradient's sum over output neurons is then vectorised (3 times faster, measured), its
rounding depending on the CPU's vector width as a BLAS product's does. The forward kernels keep
strict order: their decisions (which inputs are causal) must be the reference's.
"""

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def forward(z, w, min_excess, threads):
    """z (R, N) input spikes (inf: none), w (N, M), ``min_excess`` (``ttfs.MIN_EXCESS``) ->
    z_out (R, M) (inf: silent), order (R, N) (each row's spiking inputs in time order, then -1),
    last (R, M) (position in ``order`` of the causal set's last input; -1: silent) and excess
    (R, M) float64 (sum_C w - 1; 1 where silent). ``threads`` blocks of rows run in parallel."""
    rows, n_in = z.shape
    n_out = w.shape[1]
    z_out = np.full((rows, n_out), np.inf, dtype=z.dtype)
    last = np.full((rows, n_out), -1, dtype=np.int64)
    excess = np.ones((rows, n_out), dtype=np.float64)
    order = np.full((rows, n_in), -1, dtype=np.int64)
    per = (rows + threads - 1) // threads
    low, high = 1 - 1e-14, 1 + 1e-14
    for t in prange(threads):
        sum_w = np.empty(n_out, dtype=np.float64)  # scratch of this thread's rows
        sum_wz = np.empty(n_out, dtype=np.float64)
        open_ = np.empty(n_out, dtype=np.int64)  # 1 while the neuron has not fired
        flag = np.empty(n_out, dtype=np.int64)  # 1: passed the filter at this input
        spiking = np.empty(n_in, dtype=np.int64)
        for r in range(t * per, min(rows, (t + 1) * per)):
            row = z[r]
            k = 0
            for i in range(n_in):  # only the spiking inputs are sorted
                if np.isfinite(row[i]):
                    spiking[k] = i
                    k += 1
            idx = spiking[:k][np.argsort(row[spiking[:k]])]
            order[r, :k] = idx
            sum_w[:] = 0
            sum_wz[:] = 0
            open_[:] = 1
            remaining = n_out
            for j in range(k):
                i = idx[j]
                zj = np.float64(row[i])
                znext = np.float64(row[idx[j + 1]]) if j + 1 < k else np.inf
                hits = 0  # open neurons that may fire here (branch-free: vectorised)
                for m in range(n_out):
                    wm = np.float64(w[i, m])
                    sw = sum_w[m] + wm
                    swz = sum_wz[m] + wm * zj
                    sum_w[m] = sw
                    sum_wz[m] = swz
                    ex = sw - 1.0
                    # a filter without division, loose by a few ulps: the exact test follows
                    hit = (
                        open_[m]
                        & (ex > min_excess)
                        & (swz >= zj * ex * low)
                        & (swz < znext * ex * high)
                    )
                    flag[m] = hit
                    hits += hit
                if hits:
                    for m in range(n_out):
                        if flag[m]:
                            ex = sum_w[m] - 1.0
                            cand = sum_wz[m] / ex
                            if cand >= zj and cand < znext:
                                z_out[r, m] = cand
                                last[r, m] = j
                                excess[r, m] = ex
                                open_[m] = 0
                                remaining -= 1
                if remaining == 0:
                    break
    return z_out, order, last, excess


@njit(cache=True, parallel=True, fastmath={"reassoc"})
def backward(z, w, z_out, order, last, excess, grad_out, threads):
    """Gradients of the summed ``grad_out * z_out`` with respect to z (R, N) and w (N, M):
    for i in a neuron's causal set, dz_out/dz_i = w_i / excess and dz_out/dw_i = (z_i - z_out)
    / excess; nothing for silent neurons and inputs outside the set."""
    rows, n_in = z.shape
    n_out = w.shape[1]
    grad_z = np.zeros_like(z)
    parts = np.zeros((threads, n_in, n_out), dtype=w.dtype)  # rows summed in the weights dtype
    per = (rows + threads - 1) // threads
    for t in prange(threads):
        gw = parts[t]
        g = np.zeros(n_out, dtype=np.float64)
        gzo = np.zeros(n_out, dtype=np.float64)
        for r in range(t * per, min(rows, (t + 1) * per)):
            deepest = -1
            for m in range(n_out):
                if last[r, m] >= 0:
                    g[m] = grad_out[r, m] / excess[r, m]
                    gzo[m] = g[m] * z_out[r, m]
                    deepest = max(deepest, last[r, m])
                else:
                    g[m] = 0.0
                    gzo[m] = 0.0
            for j in range(deepest + 1):
                i = order[r, j]
                zi = np.float64(z[r, i])
                acc = 0.0
                for m in range(n_out):  # masked, branch-free: vectorised
                    causal = j <= last[r, m]
                    gm = g[m] * causal
                    acc += gm * w[i, m]
                    gw[i, m] += gm * zi - gzo[m] * causal
                grad_z[r, i] = acc
    return grad_z, parts.sum(axis=0)


@njit(cache=True)
def _field_range(pos, padding, stride, kernel, n_fields):
    """The receptive fields (first, stop) of one axis that hold input position ``pos``."""
    first = max(0, (pos + padding - kernel + stride) // stride)
    stop = min(n_fields, (pos + padding) // stride + 1)
    return first, stop


@njit(cache=True, parallel=True)
def conv_forward(z, wt, stride, padding, h_out, w_out, min_excess):
    """The convolutional layer, event by event: each sample's input spikes are sorted once
    (not once per receptive field) and delivered in time order to every receptive field that
    holds them; a field's neuron fires at the first prefix of its own inputs that is valid,
    which is known when the field's next input arrives (or at the end). Padding is "no spike":
    it never arrives.

    z (B, C, H, W) input spikes (inf: none); wt (C, k, k, C_out): the weights, output channel
    last; returns z_out (B, C_out, H_out, W_out) (inf: silent), z_last (the time of each
    neuron's last causal input; a causal set is the field's inputs at or before it) and excess
    (float64; 1 where silent)."""
    batch, channels, height, width = z.shape
    kernel = wt.shape[1]
    n_out = wt.shape[3]
    z_out = np.full((batch, n_out, h_out, w_out), np.inf, dtype=z.dtype)
    z_last = np.full((batch, n_out, h_out, w_out), -np.inf, dtype=z.dtype)
    excess = np.ones((batch, n_out, h_out, w_out), dtype=np.float64)
    low, high = 1 - 1e-14, 1 + 1e-14
    for b in prange(batch):
        flat = z[b].ravel()
        spikes = np.nonzero(np.isfinite(flat))[0]
        spikes = spikes[np.argsort(flat[spikes])]
        sum_w = np.zeros((h_out, w_out, n_out), dtype=np.float64)
        sum_wz = np.zeros((h_out, w_out, n_out), dtype=np.float64)
        prev = np.full((h_out, w_out), -np.inf)  # the field's latest input time (-inf: none)
        open_ = np.ones((h_out, w_out, n_out), dtype=np.int64)
        remaining = np.full((h_out, w_out), n_out, dtype=np.int64)
        for s in range(len(spikes) + 1):
            if s < len(spikes):
                index = spikes[s]
                c, rest = divmod(index, height * width)
                y, x = divmod(rest, width)
                t = np.float64(flat[index])
                fy0, fy1 = _field_range(y, padding, stride, kernel, h_out)
                fx0, fx1 = _field_range(x, padding, stride, kernel, w_out)
            else:  # the end: every field's last prefix, before a next input that never comes
                t = np.inf
                fy0, fy1, fx0, fx1 = 0, h_out, 0, w_out
            for fy in range(fy0, fy1):
                for fx in range(fx0, fx1):
                    zp = prev[fy, fx]
                    if remaining[fy, fx] == 0 or zp == -np.inf and s == len(spikes):
                        continue
                    if zp > -np.inf:  # did a neuron fire on the prefix before this input?
                        hits = 0
                        for m in range(n_out):
                            ex = sum_w[fy, fx, m] - 1.0
                            swz = sum_wz[fy, fx, m]
                            hits += (
                                open_[fy, fx, m]
                                & (ex > min_excess)
                                & (swz >= zp * ex * low)
                                & (swz < t * ex * high)
                            )
                        if hits:
                            for m in range(n_out):
                                ex = sum_w[fy, fx, m] - 1.0
                                if open_[fy, fx, m] and ex > min_excess:
                                    cand = sum_wz[fy, fx, m] / ex
                                    if cand >= zp and cand < t:
                                        z_out[b, m, fy, fx] = cand
                                        z_last[b, m, fy, fx] = zp
                                        excess[b, m, fy, fx] = ex
                                        open_[fy, fx, m] = 0
                                        remaining[fy, fx] -= 1
                    if s < len(spikes):
                        ky = y + padding - fy * stride
                        kx = x + padding - fx * stride
                        for m in range(n_out):
                            wm = np.float64(wt[c, ky, kx, m])
                            sum_w[fy, fx, m] += wm
                            sum_wz[fy, fx, m] += wm * t
                        prev[fy, fx] = t
    return z_out, z_last, excess


@njit(cache=True, parallel=True, fastmath={"reassoc"})
def conv_backward(z, wt, stride, padding, z_out, z_last, excess, grad_out, threads):
    """Gradients of the summed ``grad_out * z_out`` of :func:`conv_forward` with respect to z
    and to wt (C, k, k, C_out): every field's inputs at or before each neuron's ``z_last``."""
    batch, channels, height, width = z.shape
    kernel = wt.shape[1]
    n_out = wt.shape[3]
    h_out, w_out = z_out.shape[2], z_out.shape[3]
    grad_z = np.zeros((batch, channels, height, width), dtype=np.float64)
    parts = np.zeros((threads, channels, kernel, kernel, n_out), dtype=np.float64)
    per = (batch + threads - 1) // threads
    for t in prange(threads):
        gw = parts[t]
        g = np.zeros(n_out)
        gzo = np.zeros(n_out)
        limit = np.zeros(n_out)
        for b in range(t * per, min(batch, (t + 1) * per)):
            for fy in range(h_out):
                for fx in range(w_out):
                    fired = 0
                    for m in range(n_out):
                        if np.isfinite(z_out[b, m, fy, fx]):
                            g[m] = grad_out[b, m, fy, fx] / excess[b, m, fy, fx]
                            gzo[m] = g[m] * z_out[b, m, fy, fx]
                            limit[m] = z_last[b, m, fy, fx]
                            fired += 1
                        else:
                            g[m] = 0.0
                            gzo[m] = 0.0
                            limit[m] = -np.inf
                    if fired == 0:
                        continue
                    for c in range(channels):
                        for ky in range(kernel):
                            y = fy * stride - padding + ky
                            if y < 0 or y >= height:
                                continue
                            for kx in range(kernel):
                                x = fx * stride - padding + kx
                                if x < 0 or x >= width:
                                    continue
                                zi = np.float64(z[b, c, y, x])
                                if not np.isfinite(zi):
                                    continue
                                acc = 0.0
                                for m in range(n_out):  # masked, branch-free
                                    causal = zi <= limit[m]
                                    gm = g[m] * causal
                                    acc += gm * wt[c, ky, kx, m]
                                    gw[c, ky, kx, m] += gm * zi - gzo[m] * causal
                                grad_z[b, c, y, x] += acc
    return grad_z, parts.sum(axis=0)
