"""Loading simlidar datasets, under the name every dataset card gives::

    from simlidar.data import load_split, PulseDataset, EventDataset, to_events
    from simlidar.data import load_stream, StreamEventDataset  # stream splits' events

The loaders live in :mod:`simlidar.dataset.loaders` and, for stream splits' events,
:mod:`simlidar.dataset.stream_loaders` (the dataset stage); this module is their
public name, kept so that published cards and user code keep working. ``PulseDataset``
imports torch on first use, so importing this module does not. Examples: ``docs/loading.md``.
"""

from simlidar.dataset.loaders import (
    EVENT_DTYPE,
    EventDataset,
    delay_unit_ns,
    load_split,
    sensor_size,
    spike_threshold,
    split_files,
    split_path,
    to_events,
    window_ticks,
)
from simlidar.dataset.stream_loaders import StreamEventDataset, load_stream

__all__ = [  # and PulseDataset, made on first use (below)
    "EVENT_DTYPE",
    "EventDataset",
    "StreamEventDataset",
    "delay_unit_ns",
    "load_split",
    "load_stream",
    "sensor_size",
    "spike_threshold",
    "split_files",
    "split_path",
    "to_events",
    "window_ticks",
]


def __getattr__(name: str):
    if name == "PulseDataset":  # on first use: it needs torch, the rest of this module does not
        from simlidar.dataset.loaders import PulseDataset

        return PulseDataset
    raise AttributeError(f"module 'simlidar.data' has no attribute {name!r}")
