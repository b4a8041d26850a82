"""Early decisions, as the paper claims them: an event-driven run of a spiking network.

:func:`decide` runs a dense network event by event (below); :func:`decide_all` gives the same
decisions for a whole batch and for convolutional networks too, from the layer-wise spike
times (the tests hold it to :func:`decide`).

Input spikes are fed in time order; every neuron keeps the sums of the weights and of the
weighted z of the spikes it has received, and so knows when it would fire if nothing else
arrived (the closed form of :mod:`simlidar.models.ttfs`). The earliest pending event, an input
spike or a neuron's firing, is processed next; the run stops at the first output spike. On a
tie, a spike is delivered before a neuron that would fire at the same instant (the closed
form's "before the next input" is strict).

The result per sample: the class, the decision time (network time ln z and sensor
nanoseconds), the input spikes consumed and their fraction of all input spikes (the paper's
R_data), the input spikes consumed by the authors' counting rule (below), the hidden spikes
emitted before the decision, the accumulates they caused (NeuroBench's effective synaptic
operations of a spiking network: one per non-zero synapse a delivered spike reaches) and the
energy spikes x alpha.

Two counting rules for the input spikes consumed, side by side:

* ours (``input_spikes``): every input spike delivered before the decision, at any time from
  t = 0 on, and one at the very instant of the output spike too (it is delivered first);
* the authors' (``input_spikes_authors``): the test script of the paper's public code
  (``zbs881314/Temporal-Coded-Deep-SNN``) counts the inputs with ``0 < t < t_out``, t_out the
  first output spike of any output neuron: an input at exactly t = 0 (z = 1) is not counted,
  nor one at t_out. Without a decision (t_out = inf) it counts every input spike after t = 0.
"""

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from simlidar.models import ttfs
from simlidar.models.ttfs import MIN_EXCESS

ALPHAS_PJ = (0.37, 45.0)  # energy per spike in the paper's estimate, picojoules


@dataclass(frozen=True)
class Decision:
    label: int  # first output neuron to fire; -1 if none fires
    z: float  # its spike in the z domain (inf if none)
    input_spikes: int  # input spikes delivered before the decision
    input_total: int  # input spikes of the sample
    hidden_spikes: int  # spikes of hidden neurons before the decision
    accumulates: int  # synapses (non-zero weights) reached by the spikes delivered before it
    input_spikes_authors: int  # input spikes with 0 < t < t_out: the authors' count (above)

    @property
    def time(self) -> float:
        """Decision time in network time units (ln z)."""
        return float(np.log(self.z))

    @property
    def data_ratio(self) -> float:
        """R_data: the fraction of the sample's input spikes consumed before deciding."""
        return self.input_spikes / self.input_total if self.input_total else 0.0

    @property
    def spikes(self) -> int:
        """Every spike of the run: inputs consumed, hidden spikes and the output spike."""
        return self.input_spikes + self.hidden_spikes + (self.label >= 0)

    def time_ns(self, scale: float, unit_ns: float) -> float:
        """Decision time in sensor nanoseconds: network time t = scale * delay, a delay of 1.0
        being ``unit_ns`` (``tof_max_ns`` for flash pulses, the sweep window for scan-timed
        ones: :func:`simlidar.dataset.loaders.delay_unit_ns`)."""
        return self.time / scale * unit_ns

    def energy_pj(self, alpha_pj: float) -> float:
        return self.spikes * alpha_pj


def authors_count(z_in: np.ndarray, z_out: float) -> int:
    """Input spikes with 0 < t < t_out (1 < z < z_out): the authors' counting rule.

    z_in : (N,) input spikes in the z domain, inf = no spike; z_out : the decision (inf: none)
    """
    z_in = np.asarray(z_in, dtype=np.float64)
    return int(((z_in > 1.0) & (z_in < z_out) & np.isfinite(z_in)).sum())


def decide(weights: list[np.ndarray], z_in: np.ndarray) -> Decision:
    """Run a dense TTFS network on one sample, event by event, until the first output spike.

    Every input spike consumed and every hidden spike is delivered to the next layer, and adds
    one accumulate per non-zero weight it reaches (a row of that layer's weights); the output
    spike that decides is delivered nowhere.

    weights : per layer (N_in, N_out) float64 arrays, input layer first
    z_in : (N,) input spikes in the z domain, inf = no spike
    """
    z_in = np.asarray(z_in, dtype=np.float64)
    order = np.argsort(z_in, kind="stable")
    order = order[np.isfinite(z_in[order])]
    n_layers = len(weights)
    sw = [np.zeros(w.shape[1]) for w in weights]  # sum of received weights
    swz = [np.zeros(w.shape[1]) for w in weights]  # sum of received w * z
    fired = [np.zeros(w.shape[1], bool) for w in weights]
    pending = [np.full(w.shape[1], np.inf) for w in weights]  # when each would fire
    fan_out = [np.count_nonzero(w, axis=1) for w in weights]  # (N_in,) synapses per source
    hidden = 0
    accumulates = 0
    next_input = 0

    def deliver(layer: int, source: int, z: float) -> None:
        nonlocal accumulates
        accumulates += int(fan_out[layer][source])
        w = weights[layer][source]
        sw[layer] += w
        swz[layer] += w * z
        excess = sw[layer] - 1.0
        able = (excess > MIN_EXCESS) & ~fired[layer]
        candidate = np.where(able, swz[layer] / np.where(able, excess, 1.0), np.inf)
        pending[layer] = np.where(candidate >= z, candidate, np.inf)  # not before this spike

    while True:
        z_next = z_in[order[next_input]] if next_input < len(order) else np.inf
        # the earliest neuron firing, layer by layer (an earlier layer wins a tie)
        best_layer, best_neuron, best_z = -1, -1, np.inf
        for layer in range(n_layers):
            j = int(np.argmin(pending[layer]))
            if pending[layer][j] < best_z:
                best_layer, best_neuron, best_z = layer, j, pending[layer][j]
        if z_next <= best_z:  # deliver the input spike first (ties included)
            if not np.isfinite(z_next):  # nothing left to deliver or fire: undecided
                authors = authors_count(z_in, np.inf)
                return Decision(-1, np.inf, next_input, len(order), hidden, accumulates, authors)
            deliver(0, order[next_input], z_next)
            next_input += 1
            continue
        fired[best_layer][best_neuron] = True
        pending[best_layer][best_neuron] = np.inf
        if best_layer == n_layers - 1:
            authors = authors_count(z_in, best_z)
            return Decision(
                best_neuron, float(best_z), next_input, len(order), hidden, accumulates, authors
            )
        hidden += 1
        deliver(best_layer + 1, best_neuron, best_z)


def fan_outs(model, shapes: list[tuple[int, ...]], zeros: bool = False) -> list[np.ndarray]:
    """Per layer of a spiking network, the synapses (non-zero weights; with ``zeros``, every
    weight) each of its inputs reaches, flattened as the layer's input: a dense layer's weight
    row; for a convolution, the weights of every receptive field that holds the input position
    (padding connects nothing). ``shapes``: each layer's input shape without the batch."""
    out = []
    for layer, shape in zip(model.layers, shapes):
        w = layer.weight.detach()
        w = torch.ones_like(w) if zeros else w
        if w.dim() == 4:
            (_, h, wd), k, s, p = shape, w.shape[2], layer.stride, layer.padding
            h_out, w_out = (h + 2 * p - k) // s + 1, (wd + 2 * p - k) // s + 1
            extra = (h - ((h_out - 1) * s - 2 * p + k), wd - ((w_out - 1) * s - 2 * p + k))
            ones = torch.ones(1, w.shape[0], h_out, w_out, dtype=torch.float64)
            nonzero = (w != 0).double()
            reach = F.conv_transpose2d(ones, nonzero, stride=s, padding=p, output_padding=extra)
            out.append(reach.reshape(-1).round().long().numpy())
        else:
            out.append(np.count_nonzero(w.numpy(), axis=1))
    return out


def layer_shapes(model, input_shape: tuple[int, ...]) -> list[tuple[int, ...]]:
    """Each layer's input shape (without the batch) and, last, the output's."""
    shapes, z = [], torch.full((1, *input_shape), torch.inf, dtype=torch.float64)
    with torch.no_grad():
        for layer in model.layers:
            shapes.append(tuple(z.shape[1:]))
            w = layer.weight.detach().double()
            if w.dim() == 4:
                z = ttfs.conv2d(z, w, layer.stride, layer.padding)
            else:
                z = ttfs.dense(z.flatten(1), w)
    return shapes + [tuple(z.shape[1:])]


def network_size(model, input_shape: tuple[int, ...]) -> tuple[int, int]:
    """(neurons, synapses) of a spiking network: hidden and output neurons, and every
    connection from an input position to a neuron (a convolution's weights once per receptive
    field, padding excluded)."""
    shapes = layer_shapes(model, input_shape)
    neurons = sum(int(np.prod(shape)) for shape in shapes[1:])
    return neurons, int(sum(r.sum() for r in fan_outs(model, shapes[:-1], zeros=True)))


def decide_all(model, z_in: torch.Tensor) -> list[Decision]:
    """:func:`decide` for every sample of a batch and for any spiking network (dense layers and
    convolutions), from the exact spike times of the layer-wise forward pass in float64
    (``SpikingNet.propagate``, the pass that :func:`simlidar.bench.scoring.predictions` scores
    a spiking network's accuracy by: the two read the same first output spike, an exact tie
    going to the lower class index, :func:`simlidar.models.ttfs.predict`).

    A neuron's spike depends only on the spikes before it, so the event-driven run to the first
    output spike delivers exactly the spikes at or before that time (an input or hidden spike
    at the same instant goes first, as in :func:`decide`). ``tests/models/test_decisions.py``
    holds this to :func:`decide` on dense networks and on convolutions written out as dense
    layers.

    model : a ``SpikingNet``; z_in : (B, ...) its input spikes (z domain, inf = none)
    """
    with torch.no_grad():
        spikes = model.propagate(z_in.double())
    reach = fan_outs(model, [tuple(s.shape[1:]) for s in spikes[:-1]])
    inputs = [s.flatten(1).numpy() for s in spikes[:-1]]
    labels = ttfs.predict(spikes[-1]).tolist()  # the accuracy's rule, on the same spikes
    result = []
    for b, (label, out) in enumerate(zip(labels, spikes[-1].numpy())):
        z_dec = float(out[label]) if label >= 0 else np.inf
        # silent (inf) never, also when nothing decides (z_dec = inf)
        delivered = [(layer[b] <= z_dec) & np.isfinite(layer[b]) for layer in inputs]
        result.append(
            Decision(
                label,
                z_dec,
                int(delivered[0].sum()),
                int(np.isfinite(inputs[0][b]).sum()),
                int(sum(d.sum() for d in delivered[1:])),
                int(sum(r[d].sum() for r, d in zip(reach, delivered))),
                authors_count(inputs[0][b], z_dec),
            )
        )
    return result
