"""How early a trained spiking network (dense or convolutional) decides, over a whole split."""

from pathlib import Path

import numpy as np
import torch

from simlidar.dataset.loaders import load_split, spike_threshold, split_info
from simlidar.models import ttfs
from simlidar.models.decisions import ALPHAS_PJ, decide_all

BATCH = 256  # samples run at once


def decisions(model: torch.nn.Module, dataset: str | Path, split: str = "test"):
    """The decision of every sample of a split (:func:`simlidar.models.decisions.decide_all`:
    the event-driven run's, from the exact spike times), ``BATCH`` samples at a time.

    The model must be a ``SpikingNet`` (dense layers and convolutions).
    returns : list of Decision, labels (N,), time of flight at delay 1 in ns (None if the
        dataset is not a time-of-flight one)
    """
    x, y = load_split(dataset, split)
    attrs = split_info(dataset, split).attrs  # one read of the attributes
    tof_max_ns = float(attrs["tof_max_ns"]) if "tof_max_ns" in attrs else None
    silent_from = spike_threshold(attrs)
    z = ttfs.encode(torch.from_numpy(x.astype(np.float64))[:, None], model.scale, silent_from)
    runs = []
    for start in range(0, len(z), BATCH):
        runs += decide_all(model, z[start : start + BATCH])
    return runs, y, tof_max_ns


def early_decisions(
    model: torch.nn.Module, dataset: str | Path, split: str = "test", per_sample: bool = False
) -> dict:
    """Summarise :func:`decisions` over a split (means over samples, ``accumulates_mean`` being
    NeuroBench's effective synaptic operations per sample); with ``per_sample``, also the
    decision time (ns, None if undecided) and input spikes consumed of each sample."""
    runs, y, tof_max_ns = decisions(model, dataset, split)
    decided = [d for d in runs if d.label >= 0]
    spikes = np.array([d.spikes for d in runs])
    times_ns = [
        d.time_ns(model.scale, tof_max_ns) if d.label >= 0 and tof_max_ns else None for d in runs
    ]
    known = [t for t in times_ns if t is not None]
    summary = {
        "samples": len(runs),
        "accuracy": float(np.mean([d.label == t for d, t in zip(runs, y)])),
        "no_decision": len(runs) - len(decided),
        "decision_time_mean": float(np.mean([d.time for d in decided])) if decided else None,
        "decision_time_ns_mean": float(np.mean(known)) if known else None,
        "input_spikes_mean": float(np.mean([d.input_spikes for d in runs])),
        "input_spikes_total_mean": float(np.mean([d.input_total for d in runs])),
        "data_ratio_mean": float(np.mean([d.data_ratio for d in runs])),
        "hidden_spikes_mean": float(np.mean([d.hidden_spikes for d in runs])),
        "accumulates_mean": float(np.mean([d.accumulates for d in runs])),
        "energy_pj_mean": {str(a): float(spikes.mean() * a) for a in ALPHAS_PJ},
    }
    if per_sample:
        summary["per_sample"] = {
            "decision_time_ns": times_ns,
            "input_spikes": [d.input_spikes for d in runs],
        }
    return summary


def format_early(e: dict) -> str:
    """One line on how early a network decides (what ``simlidar train`` prints)."""
    when = f"{e['decision_time_ns_mean']:.0f} ns" if e["decision_time_ns_mean"] else "never"
    return (
        f"  event-driven: accuracy {e['accuracy']:.4f}, {e['input_spikes_mean']:.1f} of "
        f"{e['input_spikes_total_mean']:.1f} input spikes consumed (R_data "
        f"{e['data_ratio_mean']:.3f}), {e['hidden_spikes_mean']:.1f} hidden spikes, decision "
        f"after {when} on average, energy {e['energy_pj_mean']['0.37']:.1f} pJ at 0.37 "
        f"pJ/spike, {e['energy_pj_mean']['45.0']:.0f} pJ at 45 pJ/spike"
    )
