"""The stream task window by window (docs/streams.md, "Networks on streams"): any window model
of the registry trained on a stream dataset's rotation windows and scored on the sensor's clock
with :mod:`simlidar.bench.latency`, as a frame-based network (it answers once a rotation's
frame is complete) or, a spiking network on arrival-coded windows, as an event-driven one (it
answers at its first output spike, within the window).

* **Windows.** A stream's ``delays`` (H, R W) are its R rotations' windows side by side
  (:mod:`simlidar.dataset.stream`); rotation r's is columns r W .. (r + 1) W.
* **What a network learns from.** Each stream's windows from the one that holds its reference
  time on (its ``t_reference_us``: the object's first return, or for a stream without object
  one of its returns drawn from the same range), labelled with the stream's class: before it,
  a window of an object's stream shows no object. The validation streams are held out whole
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

import json
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
from simlidar.models.decisions import decide_all
from simlidar.models.ttfs import NEAR_FIRST
from simlidar.sensor.model import Sensor
from simlidar.sensor.rays import scan_window_ns

CUT_DEG = 180.0  # where a rotation's frame is cut: the rear, the forward window in its middle


CODINGS = ("tof", "arrival")  # what a window's value is (stream_views)


@dataclass(frozen=True)
class StreamViews:
    """A stream split seen window by window (N streams of R rotations)."""

    windows: np.ndarray  # (N, R, H, W) float32, each rotation's window, as ``coding`` says
    labels: np.ndarray  # (N,) int64
    reference_us: np.ndarray  # (N,) float64, t_reference_us
    frame_end_us: np.ndarray  # (N, R) float64, when each rotation's frame is complete
    first_rotation: np.ndarray  # (N,) int64, the window that holds the reference (or after)
    span_us: float
    classes: tuple[str, ...]  # the class names, in label order
    window_start_us: np.ndarray  # (N, R) float64, each window's first firing
    # (N, R) float64, when each window is complete: its last firing plus the longest time of
    # flight (a sector published as soon as it is scanned)
    window_end_us: np.ndarray
    unit_us: float  # an arrival-coded value of 1.0: the scan window (scan_window_ns)
    coding: str = "tof"


def stream_config(attrs: dict) -> StreamConfig:
    """The StreamConfig a stream split was made with (its ``config`` and ``sensor``)."""
    if attrs.get("source") != NAME:
        raise ConfigError(f"source {attrs.get('source')!r}: expected a stream split ({NAME!r})")
    fields = dict(attrs["config"]) | {"sensor": Sensor.from_dict(attrs["sensor"])}
    return StreamConfig(**fields)


def stream_views(dataset: str | Path, split: str, coding: str = "tof") -> StreamViews:
    """The windows, labels, reference times and frame clock of one split of a stream dataset.

    coding : what a window's value is: ``tof``, a pulse's time of flight over ``tof_max_ns``
        (the stream's ``delays``, a window dataset's flash meaning); ``arrival``, its arrival
        from its window's first firing over the scan window (a scan-timed window's meaning,
        :func:`simlidar.sensor.rays.scan_window_ns`), from the events; 1.0: no return
    """
    if coding not in CODINGS:
        raise ConfigError(f"coding={coding!r}: expected one of {list(CODINGS)}")
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
    start_us = times_ns.reshape(n, -1, rotations, width).min(axis=(1, 3)) * 1e-3
    unit_us = scan_window_ns(config.sensor, width, config.fov_deg) * 1e-3
    if coding == "arrival":
        windows = _arrivals(stream.events, start_us, unit_us, windows.shape, config.rotation_us)
    return StreamViews(
        windows=np.ascontiguousarray(windows),
        labels=labels,
        reference_us=reference,
        frame_end_us=frame_end,
        first_rotation=first.astype(np.int64),
        span_us=float(info.attrs["span_us"]),
        classes=tuple(str(c) for c in info.attrs["class_names"]),
        window_start_us=start_us,
        window_end_us=last_us + tof_max_us,
        unit_us=unit_us,
        coding=coding,
    )


def _arrivals(events, start_us: np.ndarray, unit_us: float, shape, rotation_us: float):
    """Each event's arrival from its window's first firing over ``unit_us``, placed in the
    (N, R, H, W) windows (1.0 where no event), each in its window
    (:meth:`~simlidar.dataset.stream_loaders.StreamEvents.rotations`)."""
    windows = np.ones(shape, np.float32)
    sample = np.repeat(np.arange(shape[0]), events.count)
    rotation = events.rotations(rotation_us)
    arrival = (events.t_us - start_us[sample, rotation]) / unit_us
    windows[sample, rotation, events.y, events.x] = arrival.astype(np.float32)
    return windows


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


CLOCKS = ("frame", "window")  # when a frame-based network answers (frame_answers)


def frame_answers(model, views: StreamViews, spec=None, silent_from: float = 1.0,
                  clock: str = "frame"):  # fmt: skip
    """A frame-based network's answers (:class:`~simlidar.bench.latency.Answers`, -1 where it
    gave none): its class for every rotation's window, at a time of ``clock``.

    model, spec, silent_from : the network, what it declares and the data's no-return
        threshold (:func:`~simlidar.bench.scoring.predictions`)
    views : the stream split's StreamViews (time-of-flight coded)
    clock : "frame", at the rotation's frame end (the frame cut at the rear), or "window", at
        the window's end (the forward sector published once scanned, its last pulse's time of
        flight past)
    """
    if clock not in CLOCKS:
        raise ConfigError(f"clock={clock!r}: expected one of {list(CLOCKS)}")
    n, rotations = views.windows.shape[:2]
    x = torch.from_numpy(views.windows.reshape(n * rotations, 1, *views.windows.shape[2:]))
    classes = predictions(model, x, spec=spec, silent_from=silent_from).numpy()
    ends = views.frame_end_us if clock == "frame" else views.window_end_us
    return latency.Answers.from_frames(ends, classes.reshape(n, rotations))


def decision_answers(model, views: StreamViews, batch: int = 256):
    """An event-driven network's answers (a ``SpikingNet`` on arrival-coded windows): in every
    rotation's window, its first output spike, at the window's first firing plus the spike's
    time in sensor time (:func:`simlidar.models.decisions.decide_all`, the exact event-driven
    run); a window whose outputs stay silent gives no answer."""
    if getattr(model, "direction", NEAR_FIRST) != NEAR_FIRST:
        raise ConfigError(
            f"direction={model.direction!r}: expected a network whose near (early) inputs "
            f"spike first ({NEAR_FIRST!r}): a {model.direction!r} network's spike times are "
            "not sensor time, and it would see later pulses first"
        )
    if views.coding != "arrival":
        raise ConfigError(
            f"coding={views.coding!r}: expected arrival-coded windows for an event-driven "
            "network (its spike times are then sensor time)"
        )
    n, rotations = views.windows.shape[:2]
    x = torch.from_numpy(views.windows.reshape(n * rotations, 1, *views.windows.shape[2:]))
    z = model.input_spikes(x.double())
    runs = []
    for start in range(0, len(z), batch):
        runs += decide_all(model, z[start : start + batch])
    unit_ns = views.unit_us * 1e3
    times = np.array([d.time_ns(model.scale, unit_ns) * 1e-3 if d.label >= 0 else np.nan
                      for d in runs]).reshape(n, rotations) + views.window_start_us  # fmt: skip
    classes = np.array([d.label for d in runs]).reshape(n, rotations)
    # in time order, silent windows last (an output may spike after its window's last input)
    order = np.argsort(np.where(np.isnan(times), np.inf, times), axis=1, kind="stable")
    times = np.take_along_axis(times, order, axis=1)
    classes = np.where(np.isnan(times), -1, np.take_along_axis(classes, order, axis=1))
    return latency.Answers(times, classes)


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


def read_cells(path: Path, dataset: str) -> list[dict]:
    """The cells of a resumable run (one JSON object a line, each naming its ``dataset``), all
    of ``dataset``'s: a line that is not a JSON object (a run killed while writing it) or a cell
    of another dataset is refused in one line (a ConfigError), so that no report mixes runs."""
    if not path.exists():
        return []
    cells = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        try:
            cell = json.loads(line)
        except ValueError:
            cell = None
        if not isinstance(cell, dict) or "dataset" not in cell:
            raise ConfigError(
                f"{path} line {number}: not a cell (a run killed while writing it?); expected "
                "one JSON object a line: remove the line to go on"
            )
        if cell["dataset"] != dataset:
            raise ConfigError(
                f"{path} line {number}: a cell of dataset {cell['dataset']!r}; expected "
                f"{dataset!r}'s alone: give each dataset its own --out"
            )
        cells.append(cell)
    return cells
