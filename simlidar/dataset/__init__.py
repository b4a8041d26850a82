"""Split files: their schemas (:mod:`~simlidar.dataset.schema`), versions, writer and reader,
and the loaders users read them with, re-exported here::

    from simlidar.dataset import load_split, PulseDataset, to_events

``PulseDataset`` imports torch on first use, so importing this package does not.
"""

from simlidar.dataset.loaders import (
    EVENT_DTYPE,
    load_split,
    sensor_size,
    spike_threshold,
    split_path,
    to_events,
)

__all__ = [
    "EVENT_DTYPE",
    "PulseDataset",
    "load_split",
    "sensor_size",
    "spike_threshold",
    "split_path",
    "to_events",
]


def __getattr__(name: str):
    if name == "PulseDataset":
        from simlidar.dataset.loaders import PulseDataset

        return PulseDataset
    raise AttributeError(f"module 'simlidar.dataset' has no attribute {name!r}")
