"""Compiled (numba) kernels of the dense TTFS layer: the same first spikes and gradients as the
torch form (:func:`simlidar.models.ttfs.dense_torch`), row by row.

The reference materialises every prefix of every row: (rows, inputs, outputs) cumulative sums,
whatever the prefix at which the neurons fire. These kernels sort a row's spiking inputs and
walk them in time order, keeping one running weight sum and one running weighted sum per output
neuron, and stop as soon as every neuron of the row has fired: the work is the prefix actually
used, not the whole row, and nothing larger than a row's outputs is held. The backward pass
goes input by input over every row's causal set. Rows (forward) and inputs (backward) run in
parallel (``prange``); the results do not depend on the thread count (the convolution's
weight gradient, summed from one part a thread, by float rounding only). The convolutional
layer has kernels of its own (:func:`conv_forward`): each sample's spikes are sorted once (a
radix sort, :func:`time_order`) and handed out in that order to every receptive field that
holds them, whose own walk is then the dense kernel's.

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
                    # (the convolution kernel writes this loop out again, kept so: moving it
                    # into a shared helper was not measured for speed in compiled code)
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
    / excess; nothing for silent neurons and inputs outside the set.

    Input by input (``threads`` blocks of inputs in parallel), every row's part at once: an
    input's weight row and its gradient row stay in cache while the rows are summed (in
    float64, in row order: the same result for every thread count), where a walk row by row
    would sweep the whole weight gradient once a row (9.6 MB for the SCNN's dense layer).

    z, w, z_out : the forward pass's input spikes (R, N), weights (N, M) and output spikes
        (R, M)
    order, last, excess : :func:`forward`'s: each row's spiking inputs in time order (then -1),
        the position in ``order`` of each neuron's last causal input (-1: silent) and
        sum_C w - 1 (float64; 1 where silent)
    grad_out : (R, M) the loss's gradient with respect to z_out
    threads : the blocks of inputs run in parallel
    returns : grad_z (R, N) in z's dtype and grad_w (N, M) in w's
    """
    rows, n_in = z.shape
    n_out = w.shape[1]
    grad_z = np.zeros_like(z)
    grad_w = np.empty((n_in, n_out), dtype=w.dtype)
    g = np.zeros((rows, n_out), dtype=np.float64)
    gzo = np.zeros((rows, n_out), dtype=np.float64)
    rank = np.full((rows, n_in), n_in, dtype=np.int64)  # position in the row's time order
    deepest = np.full(rows, -1, dtype=np.int64)  # the row's deepest causal position
    for r in prange(rows):
        for m in range(n_out):
            if last[r, m] >= 0:
                g[r, m] = grad_out[r, m] / excess[r, m]
                gzo[r, m] = g[r, m] * z_out[r, m]
                deepest[r] = max(deepest[r], last[r, m])
        for j in range(deepest[r] + 1):
            rank[r, order[r, j]] = j
    per = (n_in + threads - 1) // threads
    for t in prange(threads):
        gw = np.empty(n_out, dtype=np.float64)
        for i in range(t * per, min(n_in, (t + 1) * per)):
            gw[:] = 0.0
            for r in range(rows):
                j = rank[r, i]
                if j > deepest[r]:
                    continue
                zi = np.float64(z[r, i])
                acc = 0.0
                for m in range(n_out):  # masked, branch-free: vectorised
                    causal = j <= last[r, m]
                    gm = g[r, m] * causal
                    acc += gm * w[i, m]
                    gw[m] += gm * zi - gzo[r, m] * causal
                grad_z[r, i] = acc
            for m in range(n_out):
                grad_w[i, m] = gw[m]
    return grad_z, grad_w


@njit(cache=True)
def time_order(flat):
    """Indices of the finite entries of ``flat`` (times >= 0) in increasing time, ties in index
    order. A least-significant-digit radix sort of the floats' bit patterns, which order
    non-negative floats as their values (a zero is keyed 0, so -0.0 too): 11 bits a pass, a
    pass skipped where every key has the same digit (a float32's upper 32 bits). On a 48 x 25 x
    59 map, 7 to 9 times faster than numba's ``argsort`` (three runs)."""
    n = flat.size
    count = 0
    for i in range(n):
        if np.isfinite(flat[i]):
            count += 1
    idx = np.empty(count, dtype=np.int64)
    keys = np.empty(count, dtype=np.uint64)
    k = 0
    if flat.itemsize == 4:
        b32 = flat.view(np.uint32)
        for i in range(n):
            if np.isfinite(flat[i]):
                idx[k] = i
                keys[k] = np.uint64(b32[i]) if flat[i] != 0 else np.uint64(0)
                k += 1
    else:
        b64 = flat.view(np.uint64)
        for i in range(n):
            if np.isfinite(flat[i]):
                idx[k] = i
                keys[k] = b64[i] if flat[i] != 0 else np.uint64(0)
                k += 1
    idx2 = np.empty(count, dtype=np.int64)
    keys2 = np.empty(count, dtype=np.uint64)
    hist = np.empty(2048, dtype=np.int64)
    mask = np.uint64(2047)
    for p in range(6):
        shift = np.uint64(11 * p)
        hist[:] = 0
        for j in range(count):
            hist[(keys[j] >> shift) & mask] += 1
        if count == 0 or hist.max() == count:
            continue
        total = 0
        for d in range(2048):
            c = hist[d]
            hist[d] = total
            total += c
        for j in range(count):
            d = (keys[j] >> shift) & mask
            q = hist[d]
            idx2[q] = idx[j]
            keys2[q] = keys[j]
            hist[d] = q + 1
        idx, idx2 = idx2, idx
        keys, keys2 = keys2, keys
    return idx


@njit(cache=True)
def _field_range(pos, padding, stride, kernel, n_fields):
    """The receptive fields (first, stop) of one axis that hold input position ``pos``."""
    first = max(0, (pos + padding - kernel + stride) // stride)
    stop = min(n_fields, (pos + padding) // stride + 1)
    return first, stop


@njit(cache=True, parallel=True)
def conv_forward(z, wt, stride, padding, h_out, w_out, min_excess):
    """The convolutional layer: each sample's input spikes are sorted once (not once per
    receptive field, :func:`time_order`) and handed out, in that order, to every receptive
    field that holds them; then each field walks its own inputs in time order as the dense
    kernel walks a row (:func:`forward`), until all its neurons have fired. Padding is "no
    spike": it never arrives. The spikes go out in two steps, to the rows of fields and then
    to the fields of one row, so that the lists being filled stay few and in cache.

    z : (B, C, H, W) input spikes (inf: none)
    wt : (C, k, k, C_out) the weights, output channel last
    stride, padding : the step between receptive fields and the "no spike" border on each side
        of H and W, in pixels
    h_out, w_out : the output's height and width, (H + 2 padding - k) // stride + 1 and likewise
        of W (the caller computes them)
    min_excess : ``ttfs.MIN_EXCESS``: a prefix fires only where sum_C w - 1 is above it
    returns : z_out (B, C_out, H_out, W_out) (inf: silent), z_last (the time of each neuron's
        last causal input; a causal set is the field's inputs at or before it; -inf: silent)
        and excess (float64; 1 where silent), both of z_out's shape
    """
    batch, channels, height, width = z.shape
    kernel = wt.shape[1]
    n_out = wt.shape[3]
    z_out = np.full((batch, n_out, h_out, w_out), np.inf, dtype=z.dtype)
    z_last = np.full((batch, n_out, h_out, w_out), -np.inf, dtype=z.dtype)
    excess = np.ones((batch, n_out, h_out, w_out), dtype=np.float64)
    w2 = wt.reshape(channels * kernel * kernel, n_out)  # row (c * k + ky) * k + kx
    low, high = 1 - 1e-14, 1 + 1e-14
    # tables instead of integer divisions per spike (64-bit divisions cost tens of cycles):
    # each input's (c, y, x), packed, and the fields that hold each input row and column
    bits = 21
    low_bits = (1 << bits) - 1
    coords = np.empty(channels * height * width, dtype=np.int64)
    i = 0
    for c in range(channels):
        for y in range(height):
            for x in range(width):
                coords[i] = (c << (2 * bits)) | (y << bits) | x
                i += 1
    fy_lo = np.empty(height, dtype=np.int64)
    fy_hi = np.empty(height, dtype=np.int64)
    for y in range(height):
        fy_lo[y], fy_hi[y] = _field_range(y, padding, stride, kernel, h_out)
    fx_lo = np.empty(width, dtype=np.int64)
    fx_hi = np.empty(width, dtype=np.int64)
    for x in range(width):
        fx_lo[x], fx_hi[x] = _field_range(x, padding, stride, kernel, w_out)
    for b in prange(batch):
        flat = z[b].ravel()
        spikes = time_order(flat)
        n_spikes = len(spikes)
        # the spikes' positions and times in time order: one gather, then only sequential reads
        spike_at = np.empty(n_spikes, dtype=np.int64)
        spike_t = np.empty(n_spikes, dtype=np.float64)
        for s in range(n_spikes):
            spike_at[s] = coords[spikes[s]]
            spike_t[s] = flat[spikes[s]]
        # the spikes of each row of fields, in time order
        row_start = np.zeros(h_out + 1, dtype=np.int64)
        for s in range(n_spikes):
            y = (spike_at[s] >> bits) & low_bits
            for fy in range(fy_lo[y], fy_hi[y]):
                row_start[fy + 1] += 1
        for fy in range(h_out):
            row_start[fy + 1] += row_start[fy]
        row_at = np.empty(row_start[h_out], dtype=np.int64)
        row_t = np.empty(row_start[h_out], dtype=np.float64)
        fill = row_start[:-1].copy()
        for s in range(n_spikes):
            at = spike_at[s]
            y = (at >> bits) & low_bits
            for fy in range(fy_lo[y], fy_hi[y]):
                q = fill[fy]
                row_at[q] = at
                row_t[q] = spike_t[s]
                fill[fy] = q + 1
        longest = 0
        for fy in range(h_out):
            longest = max(longest, row_start[fy + 1] - row_start[fy])
        times = np.empty(longest * kernel, dtype=np.float64)  # one row's fields' inputs
        rows = np.empty(longest * kernel, dtype=np.int64)  # their rows of w2
        start = np.empty(w_out + 1, dtype=np.int64)
        pos = np.empty(w_out, dtype=np.int64)
        sum_w = np.empty(n_out, dtype=np.float64)
        sum_wz = np.empty(n_out, dtype=np.float64)
        open_ = np.empty(n_out, dtype=np.int64)
        flag = np.empty(n_out, dtype=np.int64)
        for fy in range(h_out):
            # each field of this row: its inputs in time order
            start[:] = 0
            for s in range(row_start[fy], row_start[fy + 1]):
                x = row_at[s] & low_bits
                for fx in range(fx_lo[x], fx_hi[x]):
                    start[fx + 1] += 1
            for fx in range(w_out):
                start[fx + 1] += start[fx]
            pos[:] = start[:-1]
            for s in range(row_start[fy], row_start[fy + 1]):
                at = row_at[s]
                c, y, x = at >> (2 * bits), (at >> bits) & low_bits, at & low_bits
                t = row_t[s]
                base = (c * kernel + y + padding - fy * stride) * kernel + x + padding
                for fx in range(fx_lo[x], fx_hi[x]):
                    p = pos[fx]
                    times[p] = t
                    rows[p] = base - fx * stride
                    pos[fx] = p + 1
            for fx in range(w_out):
                # the field's walk: the dense kernel's (forward), on this field's inputs
                sum_w[:] = 0
                sum_wz[:] = 0
                open_[:] = 1
                remaining = n_out
                stop = start[fx + 1]
                for j in range(start[fx], stop):
                    zj = times[j]
                    znext = times[j + 1] if j + 1 < stop else np.inf
                    wi = w2[rows[j]]
                    # the dense kernel's loop (forward), written out again: as a shared
                    # njit helper this layer ran 10-20 % slower (measured)
                    hits = 0
                    for m in range(n_out):
                        wm = np.float64(wi[m])
                        sw = sum_w[m] + wm
                        swz = sum_wz[m] + wm * zj
                        sum_w[m] = sw
                        sum_wz[m] = swz
                        ex = sw - 1.0
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
                                    z_out[b, m, fy, fx] = cand
                                    z_last[b, m, fy, fx] = zj
                                    excess[b, m, fy, fx] = ex
                                    open_[m] = 0
                                    remaining -= 1
                        if remaining == 0:
                            break
    return z_out, z_last, excess


@njit(cache=True, parallel=True, fastmath={"reassoc"})
def conv_backward(z, wt, stride, padding, z_out, z_last, excess, grad_out, threads):
    """Gradients of the summed ``grad_out * z_out`` of :func:`conv_forward` with respect to z
    and to wt (C, k, k, C_out): every field's inputs at or before each neuron's ``z_last``.

    z, wt, stride, padding : :func:`conv_forward`'s
    z_out, z_last, excess : what :func:`conv_forward` returned, (B, C_out, H_out, W_out) each
    grad_out : (B, C_out, H_out, W_out) the loss's gradient with respect to z_out
    threads : the blocks of samples run in parallel, each summing its own part of the weight
        gradient (the result depends on their count by float rounding only)
    returns : grad_z (B, C, H, W) and grad_wt (C, k, k, C_out), float64
    """
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
                    deepest = -np.inf  # inputs after every causal set are skipped
                    for m in range(n_out):
                        if np.isfinite(z_out[b, m, fy, fx]):
                            g[m] = grad_out[b, m, fy, fx] / excess[b, m, fy, fx]
                            gzo[m] = g[m] * z_out[b, m, fy, fx]
                            limit[m] = z_last[b, m, fy, fx]
                            deepest = max(deepest, limit[m])
                        else:
                            g[m] = 0.0
                            gzo[m] = 0.0
                            limit[m] = -np.inf
                    if deepest == -np.inf:
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
                                if not zi <= deepest:  # silent (inf) or after every set
                                    continue
                                acc = 0.0
                                for m in range(n_out):  # masked, branch-free
                                    causal = zi <= limit[m]
                                    gm = g[m] * causal
                                    acc += gm * wt[c, ky, kx, m]
                                    gw[c, ky, kx, m] += gm * zi - gzo[m] * causal
                                grad_z[b, c, y, x] += acc
    return grad_z, parts.sum(axis=0)
