"""Pulse streams of moving scenes (``simlidar stream``; docs/streams.md): a sample is what a
spinning sensor's window returns over several rotations while the ego drives and an object comes
into view, every pulse cast at its own emission time.

The window is the window datasets' (``width`` columns over ``fov_deg`` centred ahead, each the
firing cycle nearest its centre), taken in every rotation: rotation r's columns fire in the
cycles nearest their centres plus 360 r degrees, so the head's phase moves on from rotation to
rotation as it does on a real unit (1808.45 cycles a turn for a VLP-16 at 600 RPM;
:func:`simlidar.generator.sequences.frame_cycles`, the sweeps' own rule). t = 0 is the first
window's first firing; an event's time is its pulse's emission plus its time of flight.

Randomness: a sample's stream (:func:`simlidar.generator.simulate.sample_stream`, the window
datasets' keys) gives 2 variates for the class factor not fixed by the label, then one block an
attempt: the static scene's (:data:`~simlidar.generator.simulate.FIXED_COLUMNS` + the layout's
+ the object's, as a window's) and the scenario's (:data:`simlidar.scene.scenarios.COLUMNS`).
A stream is accepted on its geometry (the hits in range). Through a receiver (``config.profile``,
stream dataset version 1.1.0) the accepted hits then go through the window datasets' receiver
(:func:`simlidar.generator.returns.receive_hits`), its draws from the sample's receiver stream
(:func:`~simlidar.generator.returns.receiver_stream`, the window datasets' key), so the scenes
are those without a receiver. A sample's content therefore depends on (seed, split, index,
config, catalog) only.
"""

from dataclasses import dataclass

import numpy as np

from simlidar.errors import ConfigError, SimlidarError
from simlidar.generator.pulses import quantise_range
from simlidar.generator.returns import (
    check_physics,
    receive_hits,
    receiver_physics,
    receiver_stream,
)
from simlidar.generator.sequences import frame_cycles
from simlidar.generator.simulate import (
    FIXED_COLUMNS,
    SPLIT_IDS,
    class_plan,
    factors,
    layouts_seen,
)
from simlidar.generator.stream_config import StreamConfig
from simlidar.generator.streams import Streams
from simlidar.motion.poses import PlanarMotion
from simlidar.scene.build import build_batch
from simlidar.scene.recipe import Catalog
from simlidar.scene.scenarios import COLUMNS as SCENARIO_COLUMNS
from simlidar.scene.scenarios import REFERENCE_COLUMN
from simlidar.sensor.model import tof_ns
from simlidar.sensor.moving import OBJECT_CELLS, cast_moving
from simlidar.sensor.raycast import MAX_BATCH
from simlidar.sensor.rays import column_centres_deg, emission_times_ns, window_rays


@dataclass(frozen=True)
class StreamBatch:
    """A block of consecutive stream samples of one split (n samples, E events in all)."""

    labels: np.ndarray  # (n,) int64
    layout: np.ndarray  # (n,) uint8
    object: np.ndarray  # (n,) uint8
    scenario: np.ndarray  # (n,) uint8, index into the scenario names (0: none)
    t_visible_us: np.ndarray  # (n,) float64, the first event on the object; NaN without
    t_reference_us: np.ndarray  # (n,) float64, t_visible_us, or without object a drawn return's
    object_track: np.ndarray  # (n, R, 3) float32: x, y, yaw at each rotation's middle; NaN
    object_motion: np.ndarray  # (n, 3) float32: speed over the road, heading, yaw rate
    ego_motion: np.ndarray  # (n, 2) float32: speed, yaw rate
    object_events: np.ndarray  # (n,) int32, events on the object
    attempts: np.ndarray  # (n,) int32
    phase: np.ndarray  # (n,) float64, the head's phase at the first window
    event_count: np.ndarray  # (n,) int64
    event_x: np.ndarray  # (E,) uint16, column
    event_y: np.ndarray  # (E,) uint8, row (laser, highest elevation first)
    event_t_us: np.ndarray  # (E,) float64, arrival from t = 0
    event_range_m: np.ndarray  # (E,) float32, quantised range
    event_surface: np.ndarray  # (E,) uint8, surface label
    event_object: np.ndarray  # (E,) bool, on the sample's object
    event_rotation: np.ndarray  # (E,) int64, the rotation whose window fired the pulse
    # through a receiver only, else None:
    t_in_view_us: np.ndarray | None = None  # (n,) float64, the object's first hit in range
    event_intensity: np.ndarray | None = None  # (E,) uint8, the reflectivity byte


def stream_rays(config: StreamConfig, phase: np.ndarray):
    """Every pulse of the streams' windows, rotations side by side along the columns.

    phase : (n,) float64 in [0, 1), each stream's phase at its first window
    returns : origins, directions (n, H, R W, 3) float64 in the sensor's frame, emission
        times (n, H, R W) float64 ns from the first window's first firing, and each column's
        rotation (R W,) int
    """
    sensor, width, fov = config.sensor, config.width, config.fov_deg
    origins, directions, times = [], [], []
    first0 = None
    for r in range(config.rotations):
        # the cycle each column takes in rotation r: frame_cycles' rule, its frame started
        # from the window's own first cycle (the phase's, round(A_0 - phase))
        first, phase_r = frame_cycles(sensor, np.full(len(phase), r), phase)
        o, d = window_rays(sensor, width, fov, phase_r)
        base = np.round(column_centres_deg(width, fov)[0] / sensor.azimuth_step_deg - phase_r)
        if first0 is None:
            first0 = base + first
        offset_ns = (base + first - first0) * sensor.cycle_us * 1e3  # whole cycles
        times.append(emission_times_ns(sensor, width, fov, phase_r) + offset_ns[:, None, None])
        origins.append(o)
        directions.append(d)
    rotation = np.repeat(np.arange(config.rotations), width)
    return (np.concatenate(origins, axis=2), np.concatenate(directions, axis=2),
            np.concatenate(times, axis=2), rotation)  # fmt: skip


def rotation_middles_s(config: StreamConfig, times_ns: np.ndarray) -> np.ndarray:
    """Each rotation's window middle (the mean of its first and last firing), s: (n, R)."""
    t = times_ns.reshape(len(times_ns), -1, config.rotations, config.width)
    return (t.min(axis=(1, 3)) + t.max(axis=(1, 3))) * 0.5e-9


def _motions(drawn: dict, n: int):
    """The ego's and the objects' PlanarMotion from a scenario draw, fields (n, 1, 1)."""
    ego = PlanarMotion(drawn["ego_speed_mps"][:, None, None])
    things = PlanarMotion(
        drawn["speed_mps"][:, None, None],
        drawn["yaw_rate_deg_s"][:, None, None],
        drawn["heading_deg"][:, None, None],
        (drawn["x_m"][:, None, None], drawn["y_m"][:, None, None]),
    )
    return ego, things


def simulate_streams(config: StreamConfig, catalog: Catalog, split: str, start: int, stop: int):
    """Stream samples ``start .. stop - 1`` of ``split`` (at most MAX_BATCH / 2 of them):
    a :class:`StreamBatch`.

    config : what decides the samples (classes, seed, sensor, window, rotations)
    catalog : the scene recipes with their scenarios (the sensor's part and the config's
        variation are taken here)
    split : ``train`` or ``test`` (each draws from its own random streams)
    """
    if not 0 < stop - start <= OBJECT_CELLS:
        raise ConfigError(f"batch of {stop - start} streams: expected 1..{OBJECT_CELLS}")
    if catalog.scenarios is None:
        raise ConfigError(
            f"scene catalog {catalog.root} has no scenarios.toml; expected one saying how "
            "objects come into view (docs/streams.md)"
        )
    sensor = config.sensor
    catalog = catalog.for_sensor(sensor.name).with_variation(config.variation)
    scenarios = catalog.scenarios
    receiver = config.receiver_config
    if receiver is not None:
        physics = receiver_physics(receiver.profile)
        choices = check_physics(physics, sensor, catalog.surfaces)
    plan = class_plan(catalog, config.classes)
    index = np.arange(start, stop)
    n = len(index)
    labels = index % plan.classes
    streams = Streams(config.seed, SPLIT_IDS[split], index)
    free = streams.random(2)
    layout, obj = factors(plan, labels, free, len(catalog.layouts), len(catalog.objects))
    lc, oc = catalog.layout_columns, catalog.object_columns
    static = FIXED_COLUMNS + lc + oc
    azimuth = np.tile(column_centres_deg(config.width, config.fov_deg), config.rotations)
    edge = np.tan(np.deg2rad(config.fov_deg / 2.0))
    rotation_ns = 60e9 / sensor.rpm
    span_ns = config.rotations * rotation_ns
    tail_ns = scenarios.tail_ms * 1e6

    # each accepted stream's hits in range: unquantised range (NaN: none), surface, on the
    # object, |cos| of incidence (through a receiver), emission times
    shape = (n, sensor.beams, config.rotations * config.width)
    hit_m, emitted = np.full(shape, np.nan), np.zeros(shape)
    hit_surface, hit_object = np.zeros(shape, np.uint8), np.zeros(shape, bool)
    cos_incidence = np.zeros(shape, np.float32)
    attempts = np.zeros(n, np.int32)
    phase = np.zeros(n)
    drawn_all = {
        key: np.zeros(n)
        for key in (
            "scenario",
            "x_m",
            "y_m",
            "heading_deg",
            "speed_mps",
            "yaw_rate_deg_s",
            "ego_speed_mps",
        )
    }
    reference_u = np.zeros(n)
    pending = np.arange(n)
    while len(pending):
        attempts[pending] += 1
        u = streams.random(static + SCENARIO_COLUMNS, pending)
        drawn = scenarios.draw(catalog.object_names, obj[pending], u[:, static:], edge)
        pose = np.stack([drawn["x_m"], drawn["y_m"], drawn["heading_deg"]], axis=-1)
        scene = build_batch(catalog, layout[pending], obj[pending], u[:, FIXED_COLUMNS:static - oc],
                            u[:, static - oc:static], placement=pose)  # fmt: skip
        origins, directions, times_ns, _ = stream_rays(config, u[:, 0])
        ego, things = _motions(drawn, len(pending))
        times_s = times_ns * 1e-9
        hits = cast_moving(scene, origins, directions, index[pending] % MAX_BATCH,
                           sensor.max_range_m, ego.poses(times_s), things, times_s,
                           incidence=receiver is not None)  # fmt: skip
        r = quantise_range(hits.range_m, sensor)
        returned = ~np.isnan(r)
        on_object = hits.on_object & returned
        arrival_ns = np.where(returned, times_ns + tof_ns(np.nan_to_num(r)), np.inf)
        first_ns = np.where(on_object, arrival_ns, np.inf).min(axis=(1, 2))
        has = obj[pending] != 0
        ok = ~has | (
            (on_object.sum(axis=(1, 2)) >= config.min_object_hits)
            & (first_ns >= rotation_ns)
            & (first_ns <= span_ns - tail_ns)
        )
        ok &= layouts_seen(catalog, layout[pending], hits.surface, returned, azimuth)
        if plan.mode != "object":  # the layout is in the label: seen in every window
            for rotation in range(config.rotations):
                part = slice(rotation * config.width, (rotation + 1) * config.width)
                ok &= layouts_seen(catalog, layout[pending], hits.surface[..., part],
                                   returned[..., part], azimuth[part])  # fmt: skip
        done = pending[ok]
        hit_m[done] = np.where(returned[ok], hits.range_m[ok], np.nan)
        hit_surface[done] = np.where(returned[ok], hits.surface[ok], 0)
        hit_object[done], emitted[done] = on_object[ok], times_ns[ok]
        if receiver is not None:
            cos_incidence[done] = hits.cos_incidence[ok]
        phase[done] = u[ok, 0]
        for key, values in drawn.items():
            drawn_all[key][done] = values[ok]
        reference_u[done] = u[ok, static + REFERENCE_COLUMN]
        pending = pending[~ok]
        if len(pending) and attempts[pending].max() >= config.max_attempts:
            k = pending[0]
            raise SimlidarError(
                f"{split} stream {index[k]} ({plan.names[labels[k]]}): no draw in "
                f"{config.max_attempts} brought the object into view after the first rotation "
                f"and {scenarios.tail_ms:g} ms before the span's end with at least "
                f"min_object_hits={config.min_object_hits} returns, with the layout's `visible` "
                f"surface seen (width {config.width}, {config.rotations} rotations); expected "
                "scenarios (scenarios.toml) whose objects come into view within the span"
            )
    geometric_m = quantise_range(hit_m, sensor)
    in_view = _first_on_object(hit_object, emitted + tof_ns(np.nan_to_num(geometric_m)))
    if receiver is None:
        range_m, surface, intensity = geometric_m, hit_surface, None
    else:  # each stream's receiver draws: its own stream, the window datasets' key
        streams = [receiver_stream(config.seed, SPLIT_IDS[split], i) for i in index]
        got = receive_hits(receiver, physics, choices, streams, hit_m, hit_surface,
                           cos_incidence)  # fmt: skip
        range_m, surface, intensity = got.range_m, got.surface, got.intensity
    returned = ~np.isnan(range_m)
    # an event is on the object where its pulse hit the object and the return is that hit's
    # (not a false alarm's, the fog's or a drop's: surface 0)
    on_object = hit_object & returned & (surface != 0)
    arrival = np.where(returned, emitted + tof_ns(np.nan_to_num(range_m)), np.inf)
    kept = _events(range_m, surface, on_object, arrival, intensity, config)
    _, things = _motions(drawn_all, n)
    _, _, all_times, _ = stream_rays(config, phase)
    middles = rotation_middles_s(config, all_times)  # (n, R)
    moved = things.poses(middles[:, :, None])  # (n, R, 1)
    start = np.stack([drawn_all["x_m"], drawn_all["y_m"], np.zeros(n)], axis=-1)
    at = moved.to_scene(start[:, None, None, :])[:, :, 0]  # (n, R, 3)
    yaw = drawn_all["heading_deg"][:, None] + drawn_all["yaw_rate_deg_s"][:, None] * middles
    track = np.concatenate([at[..., :2], yaw[..., None]], axis=-1)
    track[obj == 0] = np.nan
    t_visible = kept.pop("t_visible_us")
    # an object the receiver never saw: its latencies count from its first hit in range
    seen_from = np.where(np.isnan(t_visible), in_view, t_visible)
    reference = _references(kept, seen_from, reference_u, rotation_ns * 1e-3,
                            (span_ns - tail_ns) * 1e-3)  # fmt: skip
    if receiver is not None:
        kept["t_in_view_us"] = in_view
    motion = np.stack([drawn_all["speed_mps"], drawn_all["heading_deg"],
                       drawn_all["yaw_rate_deg_s"]], axis=-1)  # fmt: skip
    return StreamBatch(
        labels=labels.astype(np.int64),
        layout=layout.astype(np.uint8),
        object=obj.astype(np.uint8),
        scenario=drawn_all["scenario"].astype(np.uint8),
        t_visible_us=t_visible,
        t_reference_us=reference,
        object_track=track.astype(np.float32),
        object_motion=np.where((obj != 0)[:, None], motion, 0.0).astype(np.float32),
        ego_motion=np.stack([drawn_all["ego_speed_mps"], np.zeros(n)], -1).astype(np.float32),
        attempts=attempts,
        phase=phase,
        **kept,
    )


def _references(events: dict, t_visible, u, low_us: float, high_us: float) -> np.ndarray:
    """Each stream's reference time: its object's first return (``t_visible``; through a
    receiver that saw none of its hits, its first hit in range), or for a stream without object
    the arrival of one of its returns between ``low_us`` and ``high_us`` (the range an object's
    first return is kept in), picked by its variate ``u``: a return, as an object's first is,
    so that the place in the window a figure is read at does not tell the classes apart (a
    time drawn uniformly fell between windows nine times in ten, where no object's first
    return can)."""
    reference = t_visible.copy()
    times = np.split(events["event_t_us"], np.cumsum(events["event_count"])[:-1])
    for i in np.nonzero(np.isnan(t_visible))[0]:
        inside = times[i][(times[i] >= low_us) & (times[i] <= high_us)]
        pick = min(int(u[i] * len(inside)), len(inside) - 1)
        # a stream always returns from its road; without a return in range, a time in it
        reference[i] = inside[pick] if len(inside) else low_us + u[i] * (high_us - low_us)
    return reference


def _first_on_object(on_object: np.ndarray, arrival_ns: np.ndarray) -> np.ndarray:
    """Each stream's first arrival on its object, us (NaN: none); (n, H, C) inputs."""
    first = np.where(on_object, arrival_ns, np.inf).min(axis=(1, 2)) * 1e-3
    return np.where(np.isfinite(first), first, np.nan)


def _events(range_m, surface, on_object, arrival_ns, intensity, config: StreamConfig) -> dict:
    """Each stream's returns as events in time order (ties: row, then column): ``range_m``
    (n, H, R W) quantised (NaN: no return), ``surface``, ``on_object``, ``arrival_ns`` (inf: no
    return) and, through a receiver, ``intensity`` (None without one)."""
    width = config.width
    n = len(range_m)
    fields = {k: [] for k in ("x", "y", "t", "r", "s", "o", "rot", "i")}
    count = np.zeros(n, np.int64)
    hits = np.zeros(n, np.int32)
    visible = np.full(n, np.nan)
    for i in range(n):
        t = arrival_ns[i]  # (H, R W), inf: no return
        rows, cols = np.nonzero(np.isfinite(t))
        order = np.lexsort((cols, rows, t[rows, cols]))
        rows, cols = rows[order], cols[order]
        on = on_object[i][rows, cols]
        fields["x"].append((cols % width).astype(np.uint16))
        fields["rot"].append((cols // width).astype(np.int64))
        fields["y"].append(rows.astype(np.uint8))
        fields["t"].append(t[rows, cols] * 1e-3)
        fields["r"].append(range_m[i][rows, cols].astype(np.float32))
        fields["s"].append(surface[i][rows, cols].astype(np.uint8))
        fields["o"].append(on)
        if intensity is not None:
            fields["i"].append(intensity[i][rows, cols].astype(np.uint8))
        count[i] = len(rows)
        hits[i] = on.sum()
        if on.any():
            visible[i] = fields["t"][-1][on][0]
    out = {
        "event_count": count,
        "event_x": np.concatenate(fields["x"]),
        "event_y": np.concatenate(fields["y"]),
        "event_t_us": np.concatenate(fields["t"]),
        "event_range_m": np.concatenate(fields["r"]),
        "event_surface": np.concatenate(fields["s"]),
        "event_object": np.concatenate(fields["o"]),
        "event_rotation": np.concatenate(fields["rot"]),
        "object_events": hits,
        "t_visible_us": visible,
    }
    if intensity is not None:
        out["event_intensity"] = np.concatenate(fields["i"])
    return out
