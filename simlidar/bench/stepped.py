"""How early a time-stepped spiking network (snnTorch, Norse, SpikingJelly style) decides, over
a whole split: its decision step by its declared readout (:func:`simlidar.models.protocol.
readout`), the input spikes delivered up to that step, and the spikes of its neurons.

A stepped network is given spike trains over T steps (or the same spikes as events) and returns
output spikes over T steps.
Its neurons' spikes are counted through forward hooks on its spiking neuron modules
(:func:`simlidar.bench.metrics.is_spiking_neuron`): a module called once a step gives its
spikes step by step (its k-th call of a forward pass is step k); a module called once with a
time-major output (T, B, ...) gives them along its first axis. A network whose neuron modules
are called some other number of times has its neurons' spikes counted over the whole window
(``neuron_spikes_by_step`` False in the summary).
"""

import warnings

import numpy as np
import torch

from simlidar.bench.early import BATCH
from simlidar.bench.metrics import is_spiking_neuron
from simlidar.models.decisions import ALPHAS_PJ
from simlidar.models.protocol import (
    FIRST_SPIKE,
    ModelSpec,
    arrivals,
    encode,
    readout,
    split_output,
)


class _NeuronSpikes:
    """Forward hooks that gather, per spiking neuron module, the spikes of each call of one
    forward pass: per sample, per call (a list of (B,) counts, or one (T, B) tensor)."""

    def __init__(self, model: torch.nn.Module, steps: int):
        self.steps = steps
        self.calls: dict[int, list[torch.Tensor]] = {}
        self.hooks = [
            m.register_forward_hook(self._hook(i))
            for i, m in enumerate(model.modules())
            if is_spiking_neuron(m)
        ]

    def _hook(self, index: int):
        def hook(module, inputs, out):
            spikes = out[0] if isinstance(out, tuple | list) else out
            self.calls.setdefault(index, []).append(spikes.detach())

        return hook

    def by_step(self, batch: int) -> tuple[torch.Tensor, bool]:
        """(spikes (T, B) of all neuron modules, whether step by step was known for all)."""
        total = torch.zeros(self.steps, batch, dtype=torch.float64)
        stepwise = True
        for calls in self.calls.values():
            if len(calls) == self.steps:  # one call a step
                counts = torch.stack([c.reshape(batch, -1).sum(1).double().cpu() for c in calls])
            elif len(calls) == 1 and calls[0].shape[:2] == (self.steps, batch):  # time-major
                counts = calls[0].reshape(self.steps, batch, -1).sum(2).double().cpu()
            else:  # unknown timing: the whole window's spikes, at the last step
                counts = torch.zeros(self.steps, batch, dtype=torch.float64)
                if all(c.shape[:1] == (batch,) for c in calls):  # per sample
                    counts[-1] = sum(c.reshape(batch, -1).sum(1).double().cpu() for c in calls)
                else:  # no sample axis to read: the batch's mean for every sample
                    counts[-1] = sum(float(c.sum()) for c in calls) / batch
                stepwise = False
            total += counts
        self.calls.clear()
        return total, stepwise

    def remove(self) -> None:
        for hook in self.hooks:
            hook.remove()


def stepped_decisions(
    model: torch.nn.Module,
    x: torch.Tensor,
    y: np.ndarray,
    spec: ModelSpec,
    silent_from: float,
    per_sample: bool = False,
) -> dict:
    """Summary of a stepped network's decisions over a split (means over samples).

    x : (N, 1, H, W) delays, encoded as the model declares (``spec``)
    y : (N,) labels
    silent_from : the data's no-return threshold: delays at or above it are no input spike
        (:func:`simlidar.dataset.loaders.spike_threshold`)
    per_sample : also give each sample's decision step (1 .. T, None if undecided) and input
        spikes consumed (the summary's ``per_sample``)

    ``decision_step_mean``: steps elapsed when it decided, 1 .. T, over decided samples (T for
    the "spike_count" and "membrane" readouts, which read the whole window);
    ``settled_step_mean``: the first step from which the running readout (spike counts up to
    that step) stays the final class, which needs the future and is not a causal decision;
    ``input_spikes_mean``: input spikes delivered up to and including the decision step (all of
    them for an undecided sample), of ``input_spikes_total_mean``; ``neuron_spikes_mean``:
    spikes of its neuron modules (hidden and output) up to the decision step; energy: (input
    spikes consumed + neuron spikes) x alpha, the paper's estimate.
    """
    model.eval()
    device = next(iter(model.parameters()), torch.empty(0)).device
    hooks = _NeuronSpikes(model, spec.steps)
    if not hooks.hooks:
        warnings.warn(
            f"{type(model).__name__}: no spiking neuron module recognised (snnTorch's, Norse's, "
            "SpikingJelly's or one with spiking_neuron = True): its neuron spikes count 0 and "
            "its activation sparsity is not measured",
            stacklevel=2,
        )
    predicted, steps, settled, consumed, totals, neurons = [], [], [], [], [], []
    stepwise = True
    try:
        with torch.no_grad():
            for start in range(0, len(x), BATCH):
                delays = x[start : start + BATCH].to(device)
                batch = len(delays)
                out = model(encode(delays, spec, silent_from))
                label, step = readout(out, spec)
                label, step = label.cpu(), step.cpu()
                fired, known = hooks.by_step(batch)
                stepwise &= known
                arrived = arrivals(delays, spec.steps, silent_from).double().cpu()
                at = torch.where(step >= 0, step, spec.steps - 1)
                rows = torch.arange(batch)
                consumed.append(arrived[at, rows])
                totals.append(arrived[-1])
                neurons.append(fired.cumsum(0)[at, rows])
                predicted.append(label)
                steps.append(step)
                settled.append(_settled(split_output(out, spec)[0].cpu(), label))
    finally:
        hooks.remove()
    predicted, steps = torch.cat(predicted), torch.cat(steps)
    consumed, totals, neurons = torch.cat(consumed), torch.cat(totals), torch.cat(neurons)
    settled = torch.cat(settled)
    decided = steps >= 0
    spikes = (consumed + neurons).numpy()
    summary = {
        "samples": len(y),
        "steps": spec.steps,
        "readout": spec.readout,
        "accuracy": float(np.mean(predicted.numpy() == y)),
        "no_decision": int((~decided).sum()),
        "decision_step_mean": float((steps[decided] + 1).double().mean())
        if decided.any()
        else None,
        "settled_step_mean": float((settled[decided] + 1).double().mean())
        if decided.any()
        else None,
        "input_spikes_mean": float(consumed.mean()),
        "input_spikes_total_mean": float(totals.mean()),
        "data_ratio_mean": float(np.mean(_ratio(consumed.numpy(), totals.numpy()))),
        "neuron_spikes_mean": float(neurons.mean()),
        "neuron_spikes_by_step": stepwise,
        "energy_pj_mean": {str(a): float(spikes.mean() * a) for a in ALPHAS_PJ},
    }
    if per_sample:
        summary["per_sample"] = {
            "decision_step": [int(s) + 1 if s >= 0 else None for s in steps],
            "input_spikes": [int(c) for c in consumed],
        }
    return summary


def _mean_step(steps: torch.Tensor) -> float | None:
    """Mean steps elapsed (a 0-based step + 1); None without any."""
    return float((steps + 1).double().mean()) if len(steps) else None


def _ratio(consumed: np.ndarray, totals: np.ndarray) -> np.ndarray:
    """Input spikes consumed / input spikes of the sample (1 for a sample without any)."""
    return np.divide(consumed, totals, out=np.ones_like(consumed), where=totals > 0)


def _settled(spikes: torch.Tensor, final: torch.Tensor) -> torch.Tensor:
    """Per sample (B,), the first step from which the running spike-count readout (ties to the
    lowest index) equals ``final`` at every later step; T - 1 where it never does."""
    running = spikes.cumsum(0)  # (T, B, C)
    best = running == running.max(2, keepdim=True).values
    label = best.to(torch.int8).argmax(2)  # (T, B)
    agree = (label == final[None]) & (running.sum(2) > 0)
    # the last step that disagrees, + 1; a run of agreement to the end starts there
    steps = torch.arange(1, len(agree) + 1)[:, None].expand_as(agree)
    last_bad = torch.where(~agree, steps, 0).max(0).values
    return torch.clamp(last_bad, max=len(agree) - 1)


def format_stepped(s: dict) -> str:
    """One line on how early a stepped network decides (what ``simlidar train`` prints)."""
    rule = "first output spike" if s["readout"] == FIRST_SPIKE else s["readout"].replace("_", " ")
    step = s["decision_step_mean"]
    when = f"step {step:.1f} of {s['steps']}" if step is not None else "never"
    return (
        f"decides ({rule}) at {when}, after {s['input_spikes_mean']:.1f} of "
        f"{s['input_spikes_total_mean']:.1f} input spikes; {s['neuron_spikes_mean']:.1f} neuron "
        f"spikes; no decision on {s['no_decision']} of {s['samples']} samples"
    )
