"""The stream task with a frame-based network (docs/streams.md, "Frame-based networks"): any
window model of the registry trained on a stream dataset's rotation windows and scored on the
sensor's clock with :mod:`simlidar.bench.latency`.

* **Windows.** A stream's ``delays`` (H, R W) are its R rotations' windows side by side
  (:mod:`simlidar.dataset.stream`); rotation r's is columns r W .. (r + 1) W.
* **What a network learns from.** Each stream's windows from the one that holds its reference
  time on (its ``t_reference_us``: the object's first return, or for a stream without object a
  time drawn from the same range), labelled with the stream's class: before it, a window of an
  object's stream shows no object. The validation streams are held out whole
  (:func:`~simlidar.bench.selection.validation_split` over the streams), so no stream's
  windows are on both sides.
* **When it answers.** A frame-based network sees a rotation once the rotation is complete: a
  driver publishes a scan when the head passes a cut azimuth (the Velodyne ROS driver's
  ``cut_angle``), here the rear (:data:`CUT_DEG`, 180 degrees), so that the forward window
  lies in the frame's middle. Rotation r's frame ends half a rotation after its window's
  middle, plus the longest time of flight; its answer is the network's class for rotation r's
  window (:meth:`~simlidar.bench.latency.Answers.from_frames`: its latency is this frame clock
  by construction).
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from simlidar.bench import latency
from simlidar.bench.scoring import predictions
from simlidar.bench.selection import validation_split
from simlidar.bench.train import Rows
from simlidar.dataset.loaders import load_split, split_info
from simlidar.dataset.stream import NAME
from simlidar.dataset.stream_loaders import load_stream
from simlidar.errors import ConfigError
from simlidar.generator.pulse_streams import rotation_middles_s, stream_rays
from simlidar.generator.stream_config import StreamConfig
from simlidar.sensor.model import Sensor

CUT_DEG = 180.0  # where a rotation's frame is cut: the rear, the forward window in its middle


@dataclass(frozen=True)
class StreamViews:
    """A stream split seen by a frame-based network (N streams of R rotations)."""

    windows: np.ndarray  # (N, R, H, W) float32, each rotation's window
    labels: np.ndarray  # (N,) int64
    reference_us: np.ndarray  # (N,) float64, t_reference_us
    frame_end_us: np.ndarray  # (N, R) float64, when each rotation's frame is complete
    first_rotation: np.ndarray  # (N,) int64, the window that holds the reference (or after)
    span_us: float
    classes: tuple[str, ...]  # the class names, in label order


def stream_config(attrs: dict) -> StreamConfig:
    """The StreamConfig a stream split was made with (its ``config`` and ``sensor``)."""
    if attrs.get("source") != NAME:
        raise ConfigError(f"source {attrs.get('source')!r}: expected a stream split ({NAME!r})")
    fields = dict(attrs["config"]) | {"sensor": Sensor.from_dict(attrs["sensor"])}
    return StreamConfig(**fields)


def stream_views(dataset: str | Path, split: str) -> StreamViews:
    """The windows, labels, reference times and frame clock of one split of a stream dataset."""
    info = split_info(dataset, split)
    config = stream_config(info.attrs)
    stream = load_stream(dataset, split)
    delays, labels = load_split(dataset, split)
    n, rotations, width = len(labels), config.rotations, config.width
    windows = delays.reshape(n, delays.shape[1], rotations, width).transpose(0, 2, 1, 3)
    _, _, times_ns, _ = stream_rays(config, stream.samples["phase"])
    middles_us = rotation_middles_s(config, times_ns) * 1e6  # (N, R)
    last_us = times_ns.reshape(n, -1, rotations, width).max(axis=(1, 3)) * 1e-3
    tof_max_us = config.sensor.tof_max_ns * 1e-3
    frame_end = middles_us + config.rotation_us * CUT_DEG / 360.0 + tof_max_us
    reference = stream.samples["t_reference_us"]
    first = (last_us + tof_max_us < reference[:, None]).sum(axis=1)  # windows ending before it
    return StreamViews(
        windows=np.ascontiguousarray(windows),
        labels=labels,
        reference_us=reference,
        frame_end_us=frame_end,
        first_rotation=first.astype(np.int64),
        span_us=float(info.attrs["span_us"]),
        classes=tuple(str(c) for c in info.attrs["class_names"]),
    )


def _rows(views: StreamViews, streams: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
    """The windows of ``streams`` from each one's first rotation on, (M, 1, H, W), and labels."""
    rotations = views.windows.shape[1]
    keep = np.arange(rotations)[None, :] >= views.first_rotation[streams, None]  # (S, R)
    x = views.windows[streams][keep]
    y = np.broadcast_to(views.labels[streams, None], keep.shape)[keep]
    return torch.from_numpy(x[:, None]), torch.from_numpy(np.ascontiguousarray(y))


def training_windows(views: StreamViews, seed: int, validation: float, classes: list[str]) -> Rows:
    """The training and validation rows of a stream train split: whole streams held out for
    validation (seeded by the training seed), each stream's windows from its first rotation."""
    streams, held = validation_split(views.labels, validation, seed, classes)
    x_train, y_train = _rows(views, streams)
    x_val, y_val = _rows(views, held)
    return Rows(x_train, y_train, x_val, y_val, streams)


def scored_windows(views: StreamViews) -> tuple[torch.Tensor, torch.Tensor]:
    """The test split's windows from each stream's first rotation on (the test accuracy)."""
    return _rows(views, np.arange(len(views.labels)))


def frame_answers(model, views: StreamViews, spec=None, silent_from: float = 1.0):
    """A frame-based network's answers: its class for every rotation's window, at the
    rotation's frame end (:class:`~simlidar.bench.latency.Answers`, -1 where it gave none)."""
    n, rotations = views.windows.shape[:2]
    x = torch.from_numpy(views.windows.reshape(n * rotations, 1, *views.windows.shape[2:]))
    classes = predictions(model, x, spec=spec, silent_from=silent_from).numpy()
    return latency.Answers.from_frames(views.frame_end_us, classes.reshape(n, rotations))


def latency_record(answers, views: StreamViews) -> dict:
    """The stream task's figures of one network's answers (docs/streams.md): accuracy after the
    reference, the first answer's latency, the area under the accuracy-latency curve, all on
    the sensor's clock from ``t_reference_us``."""
    after = latency.accuracy_after(answers, views.labels, views.reference_us,
                                   span_us=views.span_us)  # fmt: skip
    first = latency.decision_latency(answers, views.labels, views.reference_us)
    area = latency.area_under_curve(answers, views.labels, views.reference_us,
                                    span_us=views.span_us)  # fmt: skip
    times = np.where(answers.times_us >= views.reference_us[:, None], answers.times_us, np.inf)
    wait_ms = np.nanmin(np.where(np.isnan(times), np.inf, times), axis=1) - views.reference_us
    wait_ms = wait_ms[np.isfinite(wait_ms)] / latency.US_PER_MS
    return {
        "clock": "sensor time from t_reference_us",
        # the first answer made at or after the reference (a frame-based network's first frame
        # that may hold the object): median and range over the streams, ms
        "first_answer_after_reference_ms": {
            "median": float(np.median(wait_ms)) if len(wait_ms) else None,
            "min": float(wait_ms.min()) if len(wait_ms) else None,
            "max": float(wait_ms.max()) if len(wait_ms) else None,
            "streams": int(len(wait_ms)),
        },
        "accuracy_after": after.to_dict(),
        "first_answer": first.to_dict(),
        "area_under_curve": area.to_dict(),
    }
