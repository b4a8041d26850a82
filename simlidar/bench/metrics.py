"""What the benchmark measures on a trained model, besides accuracy.

Figures under NeuroBench's names (Yik et al. 2024) follow the definitions of its library,
NeuroBench 2.3.0, and ``tests/bench/test_metrics.py`` checks them against that library on a CNN,
an MLP, a ResNet and a snnTorch network: ``params`` (ParameterCount), ``footprint`` (Footprint:
bytes of parameters and buffers; a neuron's state, which torch keeps in a non-persistent buffer
such as snnTorch's membrane potential, is left out: it holds a batch's state, not the model),
``connection_sparsity`` (ConnectionSparsity: fraction of zero weights of the connection
layers), ``activation_sparsity`` (ActivationSparsity: fraction of zero outputs of the ReLU and
Sigmoid modules and of the spiking neuron modules, over every time step of the whole evaluated
split) and ``synaptic_operations``
(SynapticOperations: ``effective_macs``, ``effective_acs`` and ``dense`` per sample). NeuroBench
is not imported here: it brings numba, librosa, scikit-learn and a torchaudio that need not
load beside the installed torch, too much for a runtime dependency, so it is the tests' oracle
(docs/benchmark.md, "NeuroBench metrics"). For the spiking networks, which NeuroBench cannot run
(they are not snnTorch models and decide event by event), the same definitions are applied to the
event-driven run (:mod:`simlidar.models.decisions`).

Where simlidar counts what NeuroBench does not: the synapses that Norse's recurrent cells and
layers (``LIFRecurrentCell``, ``LIFRecurrent``, ...) hold themselves, ``input_weights`` and
``recurrent_weights``. NeuroBench knows only torch's connection and recurrent layers, so it
counts no operation and no connection of theirs (``SynapticOperations`` 0,
``ConnectionSparsity`` None for a network of them alone); simlidar counts them in
``connection_sparsity`` and ``synaptic_operations`` (:func:`recurrent_operations`), hence in
``energy_pj_ops``. A network without them gets NeuroBench's figures.
"""

import statistics
import time

import numpy as np
import torch
from torch import nn

from simlidar.models.decisions import network_size
from simlidar.models.layers import ConvTTFS, DenseTTFS

MAC_PJ = 4.6  # energy of a 32-bit float multiply-accumulate at 45 nm (Horowitz, ISSCC 2014)
# the layers NeuroBench counts synaptic operations and connection sparsity of (its
# STATELESS_LAYERS; torch's recurrent layers are not counted here: no model has them), and its
# activation modules
CONNECTION_LAYERS = (nn.Linear, nn.Conv1d, nn.Conv2d, nn.Conv3d)
ACTIVATIONS = (nn.ReLU, nn.Sigmoid)
AC_PJ = 0.9  # energy of a 32-bit float add (an accumulate) at 45 nm (Horowitz, ISSCC 2014)
# spiking neuron modules of outside libraries, known by a base class's module and name (no
# import of the library): snnTorch's neurons, Norse's cells and layers, SpikingJelly's nodes
# (activation_based.neuron.BaseNode); a module of any library can also say so with
# ``spiking_neuron = True``
SPIKING_BASES = {
    ("snntorch", "SpikingNeuron"),
    ("norse", "SNNCell"),
    ("norse", "SNN"),
    ("norse", "SNNRecurrentCell"),
    ("norse", "SNNRecurrent"),
    ("spikingjelly", "BaseNode"),
}
# Norse's recurrent cells (one step: input (B, in), state) and layers (all steps: input (T, B,
# in)): synapses ``input_weights`` (hidden, in) from the input and ``recurrent_weights`` (hidden,
# hidden) from the previous step's spikes (the state's ``z``), which NeuroBench leaves out
RECURRENT_CELL_BASES = {("norse", "SNNRecurrentCell")}
RECURRENT_LAYER_BASES = {("norse", "SNNRecurrent")}


def _has_base(module: nn.Module, bases: set) -> bool:
    return any((c.__module__.split(".")[0], c.__name__) in bases for c in type(module).__mro__)


def is_recurrent_synapses(module: nn.Module) -> bool:
    """Whether ``module`` is a Norse recurrent cell or layer with its own synapses
    (``input_weights``, ``recurrent_weights``)."""
    return _has_base(module, RECURRENT_CELL_BASES | RECURRENT_LAYER_BASES) and all(
        isinstance(getattr(module, name, None), torch.Tensor)
        for name in ("input_weights", "recurrent_weights")
    )


def is_spiking_neuron(module: nn.Module) -> bool:
    """Whether ``module`` is a layer of spiking neurons (its output, or the first item of a
    tuple it returns, is spikes)."""
    if getattr(module, "spiking_neuron", False):
        return True
    return _has_base(module, SPIKING_BASES)


def confusion_matrix(labels: np.ndarray, predicted: np.ndarray, classes: int) -> np.ndarray:
    """(classes, classes + 1) counts: row = true class, column = predicted; the last column
    counts samples with no prediction (a spiking network whose outputs never fired)."""
    matrix = np.zeros((classes, classes + 1), dtype=np.int64)
    np.add.at(matrix, (labels, np.where(predicted < 0, classes, predicted)), 1)
    return matrix


def footprint(model: nn.Module) -> dict:
    """NeuroBench's static metrics: ``params`` (every parameter), ``footprint`` (bytes of
    parameters and buffers) and ``connection_sparsity`` (zero weights / weights of the
    connection layers: linear and convolution layers, and the spiking layers' synapses, Norse's
    recurrent cells' input and recurrent weights included; biases, batch norm and buffers are
    not connections). NeuroBench rounds the sparsity to 4 decimals;
    it is kept whole here."""
    params = list(model.parameters())
    weights = [
        m.weight
        for m in model.modules()
        if isinstance(m, (*CONNECTION_LAYERS, DenseTTFS, ConvTTFS))
    ]
    for m in model.modules():
        if is_recurrent_synapses(m):
            weights += [m.input_weights, m.recurrent_weights]
    zeros = sum(int((w == 0).sum()) for w in weights)
    total = sum(w.numel() for w in weights)
    kept = model.state_dict(keep_vars=True)  # persistent buffers: not a batch's neuron state
    buffers = [b for name, b in model.named_buffers() if name in kept]
    size = sum(t.numel() * t.element_size() for t in (*params, *buffers))
    return {
        "params": sum(p.numel() for p in params),
        "footprint": size,
        "connection_sparsity": zeros / total if total else None,
    }


def macs(model: nn.Module, sample: torch.Tensor) -> int:
    """Multiply-accumulates per sample of a conventional network, counted by hand: every output
    of a convolution or linear layer times its full kernel (in_channels / groups x kernel, or
    in_features), zero padding included, bias excluded. Not NeuroBench's dense count, which
    leaves out the products with padding (:func:`layer_operations`).

    sample : (C, H, W) one input
    """
    count = 0

    def conv(m, inputs, out):
        nonlocal count
        count += out.numel() * m.in_channels // m.groups * int(np.prod(m.kernel_size))

    def linear(m, inputs, out):
        nonlocal count
        count += out.numel() * m.in_features

    hooks = []
    for m in model.modules():
        if isinstance(m, (nn.Conv1d, nn.Conv2d, nn.Conv3d)):
            hooks.append(m.register_forward_hook(conv))
        elif isinstance(m, nn.Linear):
            hooks.append(m.register_forward_hook(linear))
    model.eval()
    try:
        with torch.no_grad():
            model(sample[None])
    finally:
        for h in hooks:
            h.remove()
    return count


def layer_operations(layer: nn.Module, x: torch.Tensor) -> tuple[int, int]:
    """NeuroBench's synaptic operations of one connection layer on a batch: (effective, dense).

    The layer is applied with its weights and inputs made binary and its bias dropped, and the
    outputs summed. Effective: non-zero weights reaching non-zero inputs. Dense: every weight
    and every input set to 1, so that every product is counted except those with the zero
    padding of a convolution (the padded border is not an input). The dense count depends on
    shapes alone and is taken on one sample. Outputs are whole numbers, summed in float64.

    layer : one of CONNECTION_LAYERS
    x : (B, ...) the layer's input; a multi-step layer's (T, B, ...) (SpikingJelly's in
        ``step_mode="m"``) counts its T x B inputs as samples, each step once
    """
    w = layer.weight
    if isinstance(layer, nn.Linear):  # (..., in_features): any leading axes are samples
        x = x.reshape(-1, x.shape[-1])
    elif x.dim() > len(layer.kernel_size) + 2:  # a multi-step layer's (T, B, C, ...): T x B
        x = x.reshape(-1, *x.shape[x.dim() - len(layer.kernel_size) - 1 :])
    with torch.no_grad():
        ones = torch.ones_like(w)
        if isinstance(layer, nn.Linear):
            effective = nn.functional.linear((x != 0).to(w.dtype), (w != 0).to(w.dtype))
            dense = nn.functional.linear(torch.ones_like(x[:1]), ones)
        else:  # the layer's own padding mode, stride, dilation and groups
            effective = layer._conv_forward((x != 0).to(w.dtype), (w != 0).to(w.dtype), None)
            dense = layer._conv_forward(torch.ones_like(x[:1]), ones, None)
    return (int(effective.sum(dtype=torch.float64)), int(dense.sum(dtype=torch.float64)) * len(x))


def _matrix_operations(weights: torch.Tensor, x: torch.Tensor) -> tuple[int, int]:
    """(effective, dense) synaptic operations of a weight matrix (out, in) on inputs (..., in):
    non-zero weights reaching non-zero inputs, and every weight for every input row."""
    with torch.no_grad():
        x = x.reshape(-1, weights.shape[1])
        effective = nn.functional.linear(
            (x != 0).to(weights.dtype), (weights != 0).to(weights.dtype)
        )
    return int(effective.sum(dtype=torch.float64)), len(x) * weights.numel()


def recurrent_operations(module: nn.Module, args: tuple, kwargs: dict, out) -> list:
    """Synaptic operations of a Norse recurrent cell or layer's call, one entry per weight
    matrix: (effective, dense, its input). The input weights reach the call's input (a cell's
    (B, in), a layer's (T, B, in)); the recurrent weights reach the previous step's spikes: a
    cell's given state's ``z`` (none without a state: it starts at rest), a layer's initial
    state's ``z`` and then its own output spikes of each step but the last. Dense: every weight
    once a step and sample (the recurrent ones at the first step too, and autapses, zero by
    default, too)."""
    x = args[0]
    state = args[1] if len(args) > 1 else kwargs.get("state")
    hidden = module.recurrent_weights.shape[0]
    previous = getattr(state, "z", None)
    rows = x.shape[:-1]  # (B,) or (T, B)
    if previous is None:
        previous = torch.zeros((*rows[-1:], hidden), dtype=x.dtype, device=x.device)
    previous = previous.reshape(*rows[-1:], hidden).to(x.dtype)
    if len(rows) > 1:  # a layer: the state's spikes, then its own spikes of steps 0 .. T - 2
        spikes = out[0] if isinstance(out, tuple | list) else out
        previous = torch.cat([previous[None], spikes[:-1].to(x.dtype)])
    return [
        (*_matrix_operations(module.input_weights, x), x),
        (*_matrix_operations(module.recurrent_weights, previous), previous),
    ]


def workload(model: nn.Module, x: torch.Tensor, batch_size: int = 64, encode=None) -> dict:
    """NeuroBench's workload metrics of a conventional network over a whole split.

    ``activation_sparsity``: zero outputs / outputs of every ReLU and Sigmoid module, over all
    samples (None without such a module; a functional ``torch.relu``, as after a residual
    addition, is not a module and not counted, as in NeuroBench). ``synaptic_operations``: per
    sample, ``effective_macs`` and ``effective_acs`` (:func:`layer_operations`, effective; a
    layer whose input batch holds only 0, 1 and -1 is taken to receive spikes, and its
    operations are accumulates, as NeuroBench decides it batch by batch: only binary input
    data can make it so here) and ``dense``. Norse's recurrent cells and layers count too
    (:func:`recurrent_operations`: their input and recurrent weights), which NeuroBench does
    not.

    x : (N, C, H, W) inputs
    encode : what makes the model's input of a batch of ``x`` (default: ``x`` itself); a
        stepped network's layers are called once a time step, and each call is counted
    """
    counts = {"macs": 0, "acs": 0, "dense": 0, "zero": 0, "outputs": 0}

    def count(effective, dense, x):
        spikes = bool(((x == 0) | (x == 1) | (x == -1)).all())
        counts["acs" if spikes else "macs"] += effective
        counts["dense"] += dense

    def connection(m, inputs):
        count(*layer_operations(m, inputs[0]), inputs[0])

    def recurrent(m, args, kwargs, out):
        for operations in recurrent_operations(m, args, kwargs, out):
            count(*operations)

    def activation(m, inputs, out):
        out = out[0] if isinstance(out, tuple | list) else out  # snnTorch: (spikes, membrane)
        counts["zero"] += int((out == 0).sum())
        counts["outputs"] += out.numel()

    hooks = []
    for m in model.modules():
        if isinstance(m, CONNECTION_LAYERS):
            hooks.append(m.register_forward_pre_hook(connection))
        elif isinstance(m, ACTIVATIONS) or is_spiking_neuron(m):
            hooks.append(m.register_forward_hook(activation))
        if is_recurrent_synapses(m):  # a Norse recurrent cell is a neuron module too
            hooks.append(m.register_forward_hook(recurrent, with_kwargs=True))
    model.eval()
    try:
        with torch.no_grad():
            for batch in torch.split(x, batch_size):
                model(batch if encode is None else encode(batch))
    finally:
        for h in hooks:
            h.remove()
    return {
        "activation_sparsity": counts["zero"] / counts["outputs"] if counts["outputs"] else None,
        "synaptic_operations": {
            "effective_macs": counts["macs"] / len(x),
            "effective_acs": counts["acs"] / len(x),
            "dense": counts["dense"] / len(x),
        },
    }


def latency(
    model: nn.Module,
    x: torch.Tensor,
    repeats: int = 30,
    big_batch: int = 512,
    max_seconds: float = 5.0,
    encode=None,
) -> dict:
    """Inference latency at batch 1 (median of ``repeats`` runs over different samples, after
    warm-up; fewer, but at least 5, once they take ``max_seconds``) in milliseconds, and
    throughput at a large batch in samples per second.

    x : (N, C, H, W) test inputs
    big_batch : the batch of the throughput figure (the first samples of ``x``)
    encode : what makes the model's input of a batch of ``x`` (timed with the model)
    """
    encode = encode or (lambda batch: batch)
    model.eval()
    times = []
    with torch.no_grad():
        for i in range(repeats + 3):
            start = time.perf_counter()
            model(encode(x[i % len(x)][None]))
            if i >= 3:  # warm-up
                times.append(time.perf_counter() - start)
                if len(times) >= 5 and sum(times) > max_seconds:
                    break
        batch = x[:big_batch]
        model(encode(batch))
        start = time.perf_counter()
        model(encode(batch))
        seconds = time.perf_counter() - start
    return {
        "latency_ms": statistics.median(times) * 1e3,
        "latency_runs": len(times),
        "throughput_per_s": len(batch) / seconds,
        "throughput_batch": len(batch),
    }


def conventional_figures(model: nn.Module, x: torch.Tensor, board_power_w: float | None) -> dict:
    """Latency and throughput, NeuroBench's workload metrics over the split (:func:`workload`),
    the hand count of MACs (:func:`macs`) with its energy at 4.6 pJ per MAC, and the paper's own
    estimate: board power x latency.

    x : (N, C, H, W) the evaluated split
    """
    counted = macs(model, x[0])
    timing = latency(model, x)
    board = None
    if board_power_w is not None:
        board = board_power_w * timing["latency_ms"] * 1e-3 * 1e12  # W x s -> pJ
    return {
        **timing,
        "macs": counted,
        "energy_pj_mac": counted * MAC_PJ,
        "energy_pj_board": board,
        **workload(model, x),
    }


def spiking_figures(model: nn.Module, x: torch.Tensor, early: dict | None) -> dict:
    """Latency and throughput of a spiking network's batched forward pass; with the summary of
    :func:`simlidar.bench.early.early_decisions` (dense and convolutional networks), NeuroBench's
    workload metrics of the event-driven run, over the split:

    * ``activation_sparsity``: the fraction of (sample, hidden or output neuron) pairs without a
      spike before the decision. NeuroBench counts a spiking layer's zero outputs per time step;
      an event-driven run has no time steps, and a neuron spikes at most once, so each neuron
      has one output per sample.
    * ``synaptic_operations``: ``effective_acs``, accumulates per sample (one per non-zero
      synapse reached by an input or hidden spike delivered before the decision);
      ``effective_macs`` 0; ``dense``, every synapse once (each neuron spikes at most once; a
      convolution's weights once per receptive field, padding excluded).

    Without ``early`` all but ``effective_macs`` are None.
    """
    figures = {
        **latency(model, x),
        "activation_sparsity": None,
        "synaptic_operations": {"effective_macs": 0, "effective_acs": None, "dense": None},
    }
    if early is None:
        return figures
    shape = tuple(x.shape[1:])  # the delays'; a spiking network's input spikes may have more
    shape = model.encoded_shape(shape) if hasattr(model, "encoded_shape") else shape
    neurons, synapses = network_size(model, shape)  # hidden and output neurons
    fired = early["hidden_spikes_mean"] + (1 - early["no_decision"] / early["samples"])
    figures["activation_sparsity"] = 1.0 - fired / neurons
    figures["synaptic_operations"]["effective_acs"] = early["accumulates_mean"]
    figures["synaptic_operations"]["dense"] = synapses
    return figures


def stepped_figures(model: nn.Module, x: torch.Tensor, encode) -> dict:
    """A time-stepped spiking network's latency and throughput (the encoding included) and
    NeuroBench's workload metrics over every time step of the split (:func:`workload`: its
    connection layers get binary spikes, so their operations are accumulates, and its spiking
    neuron modules count in the activation sparsity), with the energy of those operations:
    accumulates x :data:`AC_PJ` plus multiply-accumulates x :data:`MAC_PJ`.

    x : (N, 1, H, W) delays; encode : a batch of them -> the model's input
    """
    work = workload(model, x, encode=encode)
    ops = work["synaptic_operations"]
    return {
        **latency(model, x, encode=encode),
        **work,
        "energy_pj_ops": ops["effective_acs"] * AC_PJ + ops["effective_macs"] * MAC_PJ,
    }
