"""How early a trained spiking network (dense or convolutional) decides, over a whole split."""

from pathlib import Path

import numpy as np
import torch

from simlidar.dataset.loaders import delay_unit_ns, load_split, spike_threshold, split_info
from simlidar.models import ttfs
from simlidar.models.decisions import ALPHAS_PJ, decide_all

BATCH = 256  # samples run at once


def decisions(model: torch.nn.Module, dataset: str | Path, split: str = "test"):
    """The decision of every sample of a split (:func:`simlidar.models.decisions.decide_all`:
    the event-driven run's, from the exact spike times), ``BATCH`` samples at a time.

    The model must be a ``SpikingNet`` (dense layers and convolutions); its inputs are
    encoded as it declares (:meth:`~simlidar.models.networks.SpikingNet.input_spikes`).
    returns : list of Decision, labels (N,), nanoseconds of a delay of 1.0
        (:func:`~simlidar.dataset.loaders.delay_unit_ns`; None if the dataset is not a LiDAR
        one, or if the network's clock is not the sensor's: a ``far_first`` encoding spikes
        far returns first, which no sensor can do before the window's end), each sample's last
        input spike as a delay (N,) (0 for a sample without any), and for a network behind an
        input budget (``input_budget``) the input spikes that had arrived by each decision,
        the gate's or not (N,) (None without a budget: they are the ones consumed)
    """
    x, y = load_split(dataset, split)
    attrs = split_info(dataset, split).attrs  # one read of the attributes
    silent_from = spike_threshold(attrs)
    delays = torch.from_numpy(x.astype(np.float64))[:, None]
    z = model.input_spikes(delays)
    runs = []
    for start in range(0, len(z), BATCH):
        runs += decide_all(model, z[start : start + BATCH])
    last = np.where(x < silent_from, x, 0.0).reshape(len(x), -1).max(axis=1, initial=0.0)
    in_sensor_time = getattr(model, "direction", ttfs.NEAR_FIRST) == ttfs.NEAR_FIRST
    arrived = None
    if getattr(model, "input_budget", None) is not None:  # the delivery rule of decide_all
        sent = model.arriving_spikes(delays).flatten(1).numpy()
        arrived = (sent <= np.array([d.z for d in runs])[:, None]).sum(axis=1)
    return runs, y, delay_unit_ns(attrs) if in_sensor_time else None, last, arrived


def early_decisions(
    model: torch.nn.Module, dataset: str | Path, split: str = "test", per_sample: bool = False
) -> dict:
    """Summarise :func:`decisions` over a split (means over samples, ``accumulates_mean`` being
    NeuroBench's effective synaptic operations per sample); with ``per_sample``, also the
    decision time (ns, None if undecided) and input spikes consumed of each sample.

    Times are sensor time: ns after the pulses' time zero, which is the flash under flash
    timing and the window's first firing under scan timing. ``last_input_ns_mean`` is when a
    sample's last input spike comes (what a network that needs every input waits for) and
    ``wait_saved_mean`` the mean fraction of that wait a decided sample did not need,
    ``1 - decision / last input``. ``clock`` says which clock the decision and the input
    spikes consumed are on (:func:`_clock`): ``sensor``, or ``network-order`` under a
    far-first encoding, whose sensor times are None (``decision_time_mean`` is network time)
    and whose ``decision_sensor_ns_mean`` is the end of the window, when every return is back.
    """
    runs, y, unit_ns, last, arrived = decisions(model, dataset, split)
    window_ns = delay_unit_ns(split_info(dataset, split).attrs)  # what a delay of 1.0 stands for
    decided = [d for d in runs if d.label >= 0]
    spikes = np.array([d.spikes for d in runs])
    times_ns = [d.time_ns(model.scale, unit_ns) if d.label >= 0 and unit_ns else None for d in runs]
    known = [t for t in times_ns if t is not None]
    saved = [1.0 - t / (w * unit_ns) for t, w in zip(times_ns, last) if t is not None and w > 0.0]
    summary = {
        "samples": len(runs),
        "accuracy": float(np.mean([d.label == t for d, t in zip(runs, y)])),
        "no_decision": len(runs) - len(decided),
        "decision_time_mean": float(np.mean([d.time for d in decided])) if decided else None,
        "decision_time_ns_mean": float(np.mean(known)) if known else None,
        "last_input_ns_mean": float(np.mean(last) * unit_ns) if unit_ns else None,
        "wait_saved_mean": float(np.mean(saved)) if saved else None,
        "input_spikes_mean": float(np.mean([d.input_spikes for d in runs])),
        "input_spikes_authors_mean": float(np.mean([d.input_spikes_authors for d in runs])),
        "input_spikes_total_mean": float(np.mean([d.input_total for d in runs])),
        "data_ratio_mean": float(np.mean([d.data_ratio for d in runs])),
        "hidden_spikes_mean": float(np.mean([d.hidden_spikes for d in runs])),
        "accumulates_mean": float(np.mean([d.accumulates for d in runs])),
        "energy_pj_mean": {str(a): float(spikes.mean() * a) for a in ALPHAS_PJ},
    }
    summary.update(_clock(unit_ns, window_ns, known, len(decided)))
    if arrived is not None:  # behind an input budget: what had arrived, let through or not
        summary["input_spikes_arrived_mean"] = float(arrived.mean())
    if per_sample:
        summary["per_sample"] = {
            "decision_time_ns": times_ns,
            "input_spikes": [d.input_spikes for d in runs],
            "input_spikes_authors": [d.input_spikes_authors for d in runs],
        }
        if arrived is not None:
            summary["per_sample"]["input_spikes_arrived"] = arrived.tolist()
    return summary


SENSOR, NETWORK_ORDER = "sensor", "network-order"  # the clocks an early figure can be on


def _clock(unit_ns, window_ns, known: list, decided: int) -> dict:
    """Which clock the summary's "decision" and input-spike counts are on (issue 42), and the
    decisions' mean in sensor time: ``sensor`` where the network's input order is the sensor's
    (near first: ns after the flash, or after the window's first firing under scan timing);
    ``network-order`` where it is not (far first spikes the far returns first, which a sensor
    delivers last: such a decision waits, in sensor time, for the whole window, ``window_ns``
    after time zero). None where the data has no sensor time (DVS) or nothing was decided."""
    if unit_ns:
        return {
            "clock": SENSOR,
            "decision_sensor_ns_mean": float(np.mean(known)) if known else None,
        }
    if window_ns is None:
        return {"clock": NETWORK_ORDER, "decision_sensor_ns_mean": None}
    return {"clock": NETWORK_ORDER, "decision_sensor_ns_mean": window_ns if decided else None}


def format_early(e: dict) -> str:
    """One line on how early a network decides (what ``simlidar train`` prints)."""
    if e["decision_time_ns_mean"]:
        when = _duration(e["decision_time_ns_mean"])
    elif e["decision_time_mean"] is not None:  # decided, but not in sensor time
        when = f"network time {e['decision_time_mean']:.3f}"
        if e.get("decision_sensor_ns_mean"):  # far first: the whole window in sensor time
            end = _duration(e["decision_sensor_ns_mean"])
            when += f" (network order; in sensor time the window's end, {end})"
    else:
        when = "never"
    if e.get("wait_saved_mean") is not None:
        when += (
            f" (last input at {_duration(e['last_input_ns_mean'])}: "
            f"{e['wait_saved_mean']:.1%} of the wait saved)"
        )
    return (
        f"  event-driven: accuracy {e['accuracy']:.4f}, {e['input_spikes_mean']:.1f} of "
        f"{e['input_spikes_total_mean']:.1f} input spikes consumed (R_data "
        f"{e['data_ratio_mean']:.3f}), {e['hidden_spikes_mean']:.1f} hidden spikes, decision "
        f"after {when} on average, energy {e['energy_pj_mean']['0.37']:.1f} pJ at 0.37 "
        f"pJ/spike, {e['energy_pj_mean']['45.0']:.0f} pJ at 45 pJ/spike"
    )


def _duration(ns: float) -> str:
    """A sensor time as people read it: 412 ns, 5.31 us, 7.42 ms."""
    if ns < 1e3:
        return f"{ns:.0f} ns"
    return f"{ns / 1e3:.3g} us" if ns < 1e6 else f"{ns / 1e6:.3g} ms"
