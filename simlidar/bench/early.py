"""How early a trained dense spiking network decides, over a whole split."""

from pathlib import Path

import h5py
import numpy as np
import torch

from simlidar.data import load_split, split_path
from simlidar.models import ttfs
from simlidar.models.events import ALPHAS_PJ, decide


def early_decisions(model: torch.nn.Module, dataset: str | Path, split: str = "test") -> dict:
    """Run :func:`simlidar.models.events.decide` on every sample of a split; summarise.

    The model must be a dense spiking network (``SpikingNet`` of dense layers).
    """
    x, y = load_split(dataset, split)
    with h5py.File(split_path(dataset, split)) as f:
        tof_max_ns = float(f.attrs["tof_max_ns"])
    weights = [m.weight.detach().double().numpy() for m in model.layers]
    z = ttfs.encode(torch.from_numpy(x.astype(np.float64)).flatten(1), model.scale).numpy()
    runs = [decide(weights, sample) for sample in z]
    decided = [d for d in runs if d.label >= 0]
    spikes = np.array([d.spikes for d in runs])
    return {
        "samples": len(runs),
        "accuracy": float(np.mean([d.label == t for d, t in zip(runs, y)])),
        "no_decision": len(runs) - len(decided),
        "decision_time_ns_mean": float(np.mean([d.time_ns(model.scale, tof_max_ns)
                                                for d in decided])) if decided else None,
        "input_spikes_mean": float(np.mean([d.input_spikes for d in runs])),
        "input_spikes_total_mean": float(np.mean([d.input_total for d in runs])),
        "data_ratio_mean": float(np.mean([d.data_ratio for d in runs])),
        "hidden_spikes_mean": float(np.mean([d.hidden_spikes for d in runs])),
        "energy_pj_mean": {str(a): float(spikes.mean() * a) for a in ALPHAS_PJ},
    }  # fmt: skip


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
