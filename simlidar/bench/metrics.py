"""What the benchmark measures on a trained model, besides accuracy.

Names follow NeuroBench (Yik et al. 2024) where it has one: ``footprint`` (bytes of parameters
and buffers), ``connection_sparsity`` (fraction of zero weights), ``activation_sparsity``
(fraction of neuron outputs that are zero, or silent for a spiking network) and
``synaptic_operations`` (multiply-accumulates of a conventional network; accumulates, one per
spike and outgoing synapse, of a spiking one).
"""

import statistics
import time

import numpy as np
import torch
from torch import nn

MAC_PJ = 4.6  # energy of a 32-bit float multiply-accumulate at 45 nm (Horowitz, ISSCC 2014)


def confusion_matrix(labels: np.ndarray, predicted: np.ndarray, classes: int) -> np.ndarray:
    """(classes, classes + 1) counts: row = true class, column = predicted; the last column
    counts samples with no prediction (a spiking network whose outputs never fired)."""
    matrix = np.zeros((classes, classes + 1), dtype=np.int64)
    np.add.at(matrix, (labels, np.where(predicted < 0, classes, predicted)), 1)
    return matrix


def footprint(model: nn.Module) -> dict:
    """Parameter count, footprint in bytes, and connection sparsity."""
    params = list(model.parameters())
    weights = [p for p in params if p.dim() > 1]
    zeros = sum(int((w == 0).sum()) for w in weights)
    total = sum(w.numel() for w in weights)
    size = sum(t.numel() * t.element_size() for t in (*params, *model.buffers()))
    return {
        "params": sum(p.numel() for p in params),
        "footprint": size,
        "connection_sparsity": zeros / total if total else 0.0,
    }


def macs(model: nn.Module, sample: torch.Tensor) -> dict:
    """Multiply-accumulates per sample of a conventional network (convolutions and linear
    layers, counted with forward hooks on one sample) and the activation sparsity of its ReLUs.

    sample : (C, H, W) one input
    """
    counts = {"macs": 0, "relu_zero": 0, "relu_total": 0}

    def conv(m, inputs, out):
        counts["macs"] += out.numel() * m.in_channels // m.groups * m.kernel_size[0] * \
            m.kernel_size[1]  # fmt: skip

    def linear(m, inputs, out):
        counts["macs"] += out.numel() * m.in_features

    def relu(m, inputs, out):
        counts["relu_zero"] += int((out == 0).sum())
        counts["relu_total"] += out.numel()

    hooks = []
    for m in model.modules():
        if isinstance(m, nn.Conv2d):
            hooks.append(m.register_forward_hook(conv))
        elif isinstance(m, nn.Linear):
            hooks.append(m.register_forward_hook(linear))
        elif isinstance(m, nn.ReLU):
            hooks.append(m.register_forward_hook(relu))
    model.eval()
    with torch.no_grad():
        model(sample[None])
    for h in hooks:
        h.remove()
    # residual blocks apply torch.relu (not a module): their outputs are not counted
    sparsity = counts["relu_zero"] / counts["relu_total"] if counts["relu_total"] else None
    return {"macs": counts["macs"], "activation_sparsity": sparsity}


def latency(model: nn.Module, x: torch.Tensor, repeats: int = 30, big_batch: int = 512,
            max_seconds: float = 5.0) -> dict:  # fmt: skip
    """Inference latency at batch 1 (median of ``repeats`` runs over different samples, after
    warm-up; fewer, but at least 5, once they take ``max_seconds``) in milliseconds, and
    throughput at a large batch in samples per second.

    x : (N, C, H, W) test inputs
    """
    model.eval()
    times = []
    with torch.no_grad():
        for i in range(repeats + 3):
            start = time.perf_counter()
            model(x[i % len(x)][None])
            if i >= 3:  # warm-up
                times.append(time.perf_counter() - start)
                if len(times) >= 5 and sum(times) > max_seconds:
                    break
        batch = x[:big_batch]
        model(batch)
        start = time.perf_counter()
        model(batch)
        seconds = time.perf_counter() - start
    return {
        "latency_ms": statistics.median(times) * 1e3,
        "latency_runs": len(times),
        "throughput_per_s": len(batch) / seconds,
        "throughput_batch": len(batch),
    }


def conventional_figures(model: nn.Module, x: torch.Tensor, board_power_w: float | None) -> dict:
    """MACs, energy at 4.6 pJ per MAC, and the paper's own estimate: board power x latency."""
    counted = macs(model, x[0])
    timing = latency(model, x)
    board = None
    if board_power_w is not None:
        board = board_power_w * timing["latency_ms"] * 1e-3 * 1e12  # W x s -> pJ
    return {
        **timing,
        "macs": counted["macs"],
        "energy_pj_mac": counted["macs"] * MAC_PJ,
        "energy_pj_board": board,
        "activation_sparsity": counted["activation_sparsity"],
        "synaptic_operations": {"effective_macs": counted["macs"], "effective_acs": 0},
    }


def spiking_figures(model: nn.Module, x: torch.Tensor, early: dict | None) -> dict:
    """Latency and throughput of a spiking network's batched forward pass; with the summary of
    :func:`simlidar.bench.early.early_decisions` (dense networks), its activation sparsity
    (neurons silent before the decision) and accumulates per decision.

    The accumulate count is exact for one hidden layer (input spikes x hidden width + hidden
    spikes x classes); it is left out (None) for deeper networks, whose evaluator does not
    count spikes per layer.
    """
    figures = {**latency(model, x), "activation_sparsity": None,
               "synaptic_operations": {"effective_macs": 0, "effective_acs": None}}  # fmt: skip
    if early is None:
        return figures
    widths = [m.weight.shape[1] for m in model.layers]
    fired = early["hidden_spikes_mean"] + (1 - early["no_decision"] / early["samples"])
    figures["activation_sparsity"] = 1.0 - fired / sum(widths)
    if len(widths) == 2:
        figures["synaptic_operations"]["effective_acs"] = (
            early["input_spikes_mean"] * widths[0] + early["hidden_spikes_mean"] * widths[1]
        )
    return figures
