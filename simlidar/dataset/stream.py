"""The stream source in one place: what the pulse-stream datasets of moving scenes declare
(:data:`SOURCE`: version line, schema, card lines, prose). Their builder is
:mod:`simlidar.generator.stream_files`; docs/streams.md describes them.

A stream split holds its samples twice over, for two kinds of network: ``delays`` (N, H, R W),
each pulse's time of flight as a window dataset's (the rotations' windows side by side: a
frame-based network reads rotation r's window from columns r W .. (r + 1) W), and the events
(E rows, ragged: ``event_start``, ``event_count``), every return with its arrival time on the
sensor's clock, in Tonic's layout (x, y, t, p), for event-driven networks.
"""

from dataclasses import replace

from simlidar.dataset.source import DELAYS_AND_LABELS, About, Source

NAME = "simlidar-stream"

ABOUT = About(
    name="Sim LiDAR pulse streams of moving scenes (simlidar)",
    # the generator's (simlidar.generator.about, a stage this one does not import; a test holds
    # them equal)
    license="cc-by-4.0",
    license_url="https://creativecommons.org/licenses/by/4.0/",
    homepage="https://pypi.org/project/simlidar/",
    tags=(
        "lidar",
        "spiking-neural-networks",
        "event-based",
        "temporal-coding",
        "velodyne-vlp-16",
        "synthetic",
        "latency",
    ),  # fmt: skip
    description=(
        "Synthetic LiDAR pulse streams: a spinning Velodyne VLP-16 on a moving car, several "
        "rotations of its forward window over a procedurally built road scene while an object "
        "(a car, a pedestrian, a truck, or none) comes into view: oncoming out of the range "
        "limit, overtaking, crossing. Every pulse is ray-cast at its own emission time, so the "
        "events carry the motion of the sensor and of the object. Each stream gives the time "
        "its object first returns (`t_visible_us`), from which a network's latency is "
        "measured on the sensor's clock."
    ),
    delay_meaning=(
        "`delays`: a pulse's round-trip time of flight divided by that at the sensor's maximum "
        "range (`tof_max_ns`); 1.0 means no return. Row r is a laser (highest elevation "
        "first), column c the window's column c % W of rotation c // W. The events: one per "
        "return, x the window's column, y the row, t its arrival in microseconds from the "
        "stream's first firing (emission plus time of flight), p 0."
    ),
    conversion=(
        "Each stream draws a static scene as the window datasets do (layout and object "
        "parameters), then its scenario (scenarios.toml: how its object starts and moves) and "
        "the ego's speed. The sensor's window is cast in every rotation, each pulse at its "
        "emission time against the ego's pose and the object's at that time. A stream is "
        "redrawn until its object first returns after the window's first rotation, before the "
        "span's last `tail_ms` and at least `min_object_hits` times in all, and its layout is "
        "seen as the window datasets require."
    ),
    uses="Benchmarking how soon after an object comes into view a network recognises it "
    "(accuracy against time from `t_visible_us`), frame-based and event-driven alike.",
    out_of_scope="Synthetic scenes of one object each with simple geometry; no receiver noise "
    "or weather in this version. Not a substitute for recorded data.",
    source_citation="""@inproceedings{wang2020temporal,
  title     = {Temporal Pulses Driven Spiking Neural Network for Fast Object Recognition in
               Autonomous Driving},
  author    = {Wang, Wei and Zhou, Shibo and Li, Jingxi and Li, Xiaohua and Yuan, Junsong and
               Jin, Zhanpeng},
  booktitle = {Proceedings of the Twenty-Ninth International Joint Conference on Artificial
               Intelligence (IJCAI-20)},
  pages     = {828--834},
  year      = {2020}
}""",
)

# streams without a receiver are still written as 1.0.0, byte for byte (their records have
# not changed); StreamConfig.version
UNRECEIVED_VERSION = "1.0.0"

# a stream through a receiver says so (streams without one keep 1.0.0's card, byte for byte)
RECEIVER_ABOUT = replace(
    ABOUT,
    out_of_scope="Synthetic scenes of one object each with simple geometry, seen through a "
    "simulated receiver calibrated to published sensor figures (docs/sensor-model.md). Not a "
    "substitute for recorded data.",
)

SOURCE = Source(
    name=NAME,
    version="1.1.0",
    dates={"1.0.0": "2026-11-28", "1.1.0": "2026-11-28"},
    notes={
        "1.0.0": (
            "First release (issue 60): pulse streams of moving scenes, several rotations of a "
            "spinning sensor's window with every pulse cast at its own time, as dense times of "
            "flight and ragged events with surface labels, the time each object first returns "
            "and its track."
        ),
        "1.1.0": (
            "Streams through a receiver (`--profile sensor`, with `--fog V` or `--rain R`): the "
            "calibrated receiver of dataset version 5.0.0 decides which hits are events, with "
            "its range noise, false alarms and, in weather, the fog's and the drops' echoes "
            "(events of surface 0). New datasets `event_intensity` (the reflectivity byte) and "
            "`t_in_view_us` (the object's first hit, detected or not); `t_visible_us` is the "
            "first detected event on the object; attributes `receiver` and `materials`. Fields "
            "added, hence a new MINOR; streams without a receiver keep 1.0.0 and its bytes."
        ),
    },
    schema={
        **DELAYS_AND_LABELS,
        "layout": ("uint8", ("N",)),
        "object": ("uint8", ("N",)),
        "scenario": ("uint8", ("N",)),
        "t_visible_us": ("float64", ("N",)),
        "t_reference_us": ("float64", ("N",)),
        "object_track": ("float32", ("N", "R", 3)),
        "object_motion": ("float32", ("N", 3)),
        "ego_motion": ("float32", ("N", 2)),
        "object_events": ("int32", ("N",)),
        "attempts": ("int32", ("N",)),
        "phase": ("float64", ("N",)),
        "event_start": ("int64", ("N",)),
        "event_count": ("int64", ("N",)),
        "event_x": ("uint16", ("E",)),
        "event_y": ("uint8", ("E",)),
        "event_t_us": ("float64", ("E",)),
        "event_p": ("uint8", ("E",)),
        "event_range_m": ("float32", ("E",)),
        "event_surface": ("uint8", ("E",)),
    },
    attrs=(
        "classes",
        "input_sha256",
        "layout_names",
        "object_names",
        "surface_names",
        "scenario_names",
        "scenarios",
        "catalog",
        "rotations",
        "rotation_us",
        "span_us",
        "tof_max_ns",
        "row_laser_ids",
        "row_elevation_deg",
        "column_azimuth_deg",
        "min_object_hits",
    ),
    fields={
        "delays": "each pulse's time of flight over `tof_max_ns` (1.0 = no return), the "
        "rotations' windows side by side",
        "labels": "class index",
        "layout": "layout id (index into `layout_names`)",
        "object": "object id (index into `object_names`; 0: none)",
        "scenario": "how the object comes into view (index into `scenario_names`; 0: none)",
        "t_visible_us": "arrival of the first event on the object, us from the first firing "
        "(NaN: no object)",
        "t_reference_us": "the time latencies count from: `t_visible_us`, or for a stream "
        "without object the arrival of one of its returns, drawn from the same range",
        "object_track": "the object's x, y (m) and yaw (deg) in the scene frame at each "
        "rotation's window middle (NaN: no object)",
        "object_motion": "the object's speed over the road (m/s), heading and yaw rate as drawn",
        "ego_motion": "the ego's speed (m/s) and yaw rate (deg/s)",
        "object_events": "events on the object",
        "attempts": "draws until the stream was accepted",
        "phase": "the head's phase at the first window, in azimuth steps",
        "event_start": "row of the sample's first event in the event_* datasets",
        "event_count": "number of events of the sample",
        "event_x": "event column in the window (0-based)",
        "event_y": "event row: the laser, highest elevation first",
        "event_t_us": "event arrival, microseconds from the stream's first firing",
        "event_p": "event polarity: 0 (one return a pulse)",
        "event_range_m": "event range (m), quantised to the sensor's resolution",
        "event_surface": "event surface label (index into `surface_names`)",
    },
    call=("simlidar.generator.stream_files", "generate_streams", None),
    about=ABOUT,
    receiver_about=RECEIVER_ABOUT,
    receiver_schema={
        "t_in_view_us": ("float64", ("N",)),
        "event_intensity": ("uint8", ("E",)),
    },
    receiver_fields={
        "t_visible_us": "arrival of the first event on the object, us from the first firing "
        "(NaN: no object, or the receiver detected none of its hits)",
        "t_reference_us": "the time latencies count from: `t_visible_us`; where the receiver "
        "detected none of the object's hits, `t_in_view_us`; for a stream without object the "
        "arrival of one of its returns, drawn from the same range",
        "t_in_view_us": "the object's first hit in range, detected or not, us from the first "
        "firing (NaN: no object)",
        "event_intensity": "event reflectivity byte, as the sensor reports it (0-100 diffuse, "
        "101-255 retro-reflective)",
    },
)
