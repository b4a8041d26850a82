"""Ray origins and directions of a sample window.

A sample is a window of the sensor's H lasers (rows, highest elevation first) x ``width``
azimuth columns spread evenly over ``fov_deg`` degrees centred straight ahead. Column ``c``
covers the azimuth bin ``[-fov/2 + c * fov/W, -fov/2 + (c + 1) * fov/W)`` and takes the *centre
firing*: the firing cycle whose start azimuth lies nearest the bin centre, each laser at its own
firing time inside that cycle (a laser in firing slot ``k`` fires ``k * firing_interval_us``
after the cycle starts; a VLP-16's laser id ``j`` is slot ``j``, 2.304 us apart), turned by its
rotational correction where the sensor file gives one. The head's
rotation phase relative to the scene is a per-sample number ``phase`` in [0, 1) (a fraction of
one cycle's azimuth step). See ``docs/sensor-model.md`` for why.

The same firings give each pulse its emission time within the sweep
(:func:`emission_times_ns`), from which scan-timed pulses are made (``--timing scan``).
"""

import numpy as np

from simlidar.errors import ConfigError, shown
from simlidar.sensor.model import Sensor, row_order

# The most pulses one rotation of a sensor may fire (a sweep's frame: beams x firing cycles, from
# the sensor file's elevations_deg, rpm and cycle_us): 8 x the largest a shipped sensor can be
# set to (the HDL-64E at its slowest 300 RPM, 64 x 4166 = 266,624; at its 600, 133,312) and 4.5 x
# a sensor of the most beams a file may list (128) firing every 0.1 deg (460,800). A frame's
# arrays then stay within 16 MiB each (the dual returns, (H, C, 2) float32, and the emission
# times, (H, C) float64), far under the largest chunk a reader inflates
# (simlidar.dataset.storage.MAX_CHUNK_BYTES). A VLP-16 file of 0.001 RPM asked for 1.7e10.
MAX_ROTATION_PULSES = 2**21


def column_centres_deg(width: int, fov_deg: float) -> np.ndarray:
    """Azimuth of each column's bin centre, degrees, left (negative) to right: (W,) float64."""
    bin_deg = fov_deg / width
    return -fov_deg / 2.0 + (np.arange(width) + 0.5) * bin_deg


def _cycles(sensor: Sensor, width: int, fov_deg: float, phase):
    """Index of the firing cycle each column takes (the one whose start azimuth lies nearest
    the bin centre), counted from the cycle that starts at azimuth ``phase`` steps:
    (B, W) float64, and the phase as (B,) float64."""
    phase = np.asarray(phase, dtype=np.float64)
    centres = column_centres_deg(width, fov_deg)  # (W,)
    return np.round(centres[None, :] / sensor.azimuth_step_deg - phase[:, None]), phase


def _azimuth_parts(sensor: Sensor, width: int, fov_deg: float, phase):
    """Cycle start of each column (B, 1, W) and firing offset of each row (1, H, 1), degrees."""
    cycle, phase = _cycles(sensor, width, fov_deg, phase)
    cycle_start = ((cycle + phase[:, None]) * sensor.azimuth_step_deg)[:, None, :]
    return cycle_start, _firing_offsets_deg(sensor)


def _firing_offsets_deg(sensor: Sensor) -> np.ndarray:
    """Azimuth of each row's laser from its cycle's start (firing slot, rotational
    correction): (1, H, 1) degrees."""
    lasers = row_order(sensor)
    firing = np.asarray([sensor.slots[k] for k in lasers], dtype=np.float64)
    firing = firing * sensor.firing_step_deg
    if sensor.rot_corrections_deg:  # beam azimuth = head azimuth - rotational correction
        firing = firing - np.asarray([sensor.rot_corrections_deg[k] for k in lasers])
    return firing[None, :, None]


def firing_azimuths_deg(sensor: Sensor, width: int, fov_deg: float, phase) -> np.ndarray:
    """Azimuth of each pulse of a window.

    phase : (B,) float, in [0, 1)
    returns : (B, H, W) float64, rows in :func:`row_order`
    """
    cycle_start, firing = _azimuth_parts(sensor, width, fov_deg, phase)
    return cycle_start + firing


def emission_times_ns(sensor: Sensor, width: int, fov_deg: float, phase) -> np.ndarray:
    """When each pulse of a window leaves the sensor, in ns from the window's first firing.

    Column ``c`` fires in cycle ``k_c`` (:func:`firing_azimuths_deg`), laser ``j`` in its slot
    ``s_j``: ``t = (k_c - k_0) * cycle_us + s_j * firing_interval_us`` (x 1000). Columns run
    left to right, the way the head turns, so time grows with the column; the phase decides
    which cycle a column takes and so moves a column's times by whole cycles.

    phase : (B,) float in [0, 1)
    returns : (B, H, W) float64, rows in :func:`row_order`
    """
    cycle, _ = _cycles(sensor, width, fov_deg, phase)
    return _emission_ns(sensor, cycle - cycle[:, :1])


def _emission_ns(sensor: Sensor, cycles: np.ndarray) -> np.ndarray:
    """Emission time of every row's laser in cycles ``cycles`` (B, W) counted from the first
    firing's: (B, H, W) float64 ns."""
    slots = np.asarray([sensor.slots[k] for k in row_order(sensor)], dtype=np.float64)
    firing = slots * sensor.firing_interval_us  # (H,), us
    return (cycles[:, None, :] * sensor.cycle_us + firing[None, :, None]) * 1000.0


def cycles_per_rotation(sensor: Sensor) -> int:
    """Firing cycles of one full rotation: 1808 for a VLP-16 at 600 RPM (100 ms / 55.296 us;
    the 0.4 cycle left over belongs to the next rotation). A ConfigError naming the sensor's
    ``rpm`` and ``cycle_us`` where a rotation would fire more than :data:`MAX_ROTATION_PULSES`
    pulses: every array of a full rotation is sized from this number."""
    cycles = 60e6 / sensor.rpm // sensor.cycle_us  # a float: it may be beyond any integer type
    if not sensor.beams * cycles <= MAX_ROTATION_PULSES:
        raise ConfigError(
            f"sensor {sensor.name}: rpm={shown(sensor.rpm)}, cycle_us={shown(sensor.cycle_us)}: "
            f"a rotation of {sensor.beams} beams x {cycles:.4g} firing cycles = "
            f"{sensor.beams * cycles:.4g} pulses; expected at most {MAX_ROTATION_PULSES} pulses "
            "a rotation (a sweep's frame): a higher rpm or a longer cycle_us"
        )
    return int(cycles)


def sweep_emission_ns(sensor: Sensor) -> np.ndarray:
    """When each firing of a full rotation (:func:`sweep_rays`) leaves the sensor, ns from the
    rotation's first firing: (H, C) float64, the same for every rotation."""
    return _emission_ns(sensor, np.arange(cycles_per_rotation(sensor), dtype=np.float64)[None])[0]


def sweep_azimuths_deg(sensor: Sensor, phase) -> np.ndarray:
    """Azimuth of every firing of B full rotations, degrees: cycle ``k`` starts at
    ``-180 + (k + phase) * azimuth_step_deg`` (behind the sensor, turning clockwise through
    the front), each laser at its firing offset. phase : (B,) -> (B, H, C) float64."""
    return sum(_sweep_parts(sensor, phase))


def _sweep_parts(sensor: Sensor, phase):
    """Cycle start (B, 1, C) and firing offset (1, H, 1) of every firing of B rotations, deg."""
    phase = np.asarray(phase, dtype=np.float64)
    k = np.arange(cycles_per_rotation(sensor), dtype=np.float64)
    start = -180.0 + (k[None, :] + phase[:, None]) * sensor.azimuth_step_deg
    return start[:, None, :], _firing_offsets_deg(sensor)


def sweep_rays(sensor: Sensor, phase, compiled: bool = False):
    """Origins and unit directions of every firing of B full rotations (frames), as
    :func:`window_rays` gives those of a window: (B, H, C, 3) each, C =
    :func:`cycles_per_rotation`."""
    return _rays(sensor, *_sweep_parts(sensor, phase), compiled)


def scan_window_ns(sensor: Sensor, width: int, fov_deg: float) -> float:
    """A bound on every pulse's arrival time in a window of scan-timed pulses, ns from the
    window's first firing: the head's time to turn from the first to the last column's centre
    (``fov_deg * (width - 1) / width``), two cycles (the columns' cycles are rounded to the
    nearest, and the last slot fires inside its cycle) and the time of flight at maximum
    range. Scan-timed delays are arrival times divided by it (``delay_unit_ns``), so every
    return lies in (0, 1). About 9.49 ms for a VLP-16 at 600 RPM over 16 columns of 36
    degrees."""
    turn_us = fov_deg * (width - 1) / width / sensor.degrees_per_us
    return (turn_us + 2.0 * sensor.cycle_us) * 1000.0 + sensor.tof_max_ns


def _pitch(vectors: np.ndarray, pitch_deg: float) -> np.ndarray:
    """Tilt (..., 3) vectors forward by ``pitch_deg`` (positive looks down)."""
    t = np.deg2rad(pitch_deg)
    x, y, z = vectors[..., 0], vectors[..., 1], vectors[..., 2]
    return np.stack([x * np.cos(t) + z * np.sin(t), y, z * np.cos(t) - x * np.sin(t)], axis=-1)


def window_rays(sensor: Sensor, width: int, fov_deg: float, phase, compiled: bool = False):
    """Origins and unit directions of every pulse of B sample windows.

    width, fov_deg : the window's columns and its horizontal field of view (degrees)
    phase : (B,) float in [0, 1)
    compiled : the products in a compiled kernel (:func:`simlidar.sensor.cast_kernels.rays`:
        the same numbers; asked on long runs, :func:`simlidar.sensor.raycast.compiled_for`)
    returns : origins (B, H, W, 3) float64, directions (B, H, W, 3) float64, in the sample's
        local frame (road at z = 0, rotation axis at x = y = 0).
    """
    return _rays(sensor, *_azimuth_parts(sensor, width, fov_deg, phase), compiled)


def _rays(sensor: Sensor, cycle_start_deg: np.ndarray, firing_deg: np.ndarray, compiled=False):
    """Origins and directions of the firings at azimuth cycle start (B, 1, W) + firing offset
    (1, H, 1) degrees: (B, H, W, 3) each (``compiled``: the products by a kernel)."""
    cycle_start, firing = np.deg2rad(cycle_start_deg), np.deg2rad(firing_deg)
    lasers = row_order(sensor)
    elevation = np.deg2rad(np.asarray(sensor.elevations_deg)[lasers])[None, :, None]
    # every window has the same H origins: the emitters on the axis, tilted with the sensor
    row_origins = np.zeros((sensor.beams, 3))
    row_origins[:, 2] = np.asarray(sensor.vertical_offsets_mm)[lasers] * 1e-3
    row_origins = _pitch(row_origins, sensor.pitch_deg)
    row_origins[:, 2] += sensor.mount_height_m
    # azimuth = cycle start + firing offset; expand cos/sin of the sum instead of (B, H, W) trig
    # (numpy's own cos and sin, on these arrays, in either form)
    cos_start, sin_start = np.cos(cycle_start), np.sin(cycle_start)
    cos_firing, sin_firing = np.cos(firing), np.sin(firing)
    cos_elevation, sin_elevation = np.cos(elevation), np.sin(elevation)
    if compiled:
        from simlidar.sensor import cast_kernels

        origins, directions = cast_kernels.rays(
            cos_start[:, 0], sin_start[:, 0], cos_firing[0, :, 0], sin_firing[0, :, 0],
            cos_elevation[0, :, 0], sin_elevation[0, :, 0], row_origins,
        )  # fmt: skip
    else:
        cos_a = cos_start * cos_firing - sin_start * sin_firing
        sin_a = sin_start * cos_firing + cos_start * sin_firing
        directions = np.empty(cos_a.shape + (3,))
        directions[..., 0] = cos_elevation * cos_a
        directions[..., 1] = -cos_elevation * sin_a  # clockwise azimuth: positive looks right
        directions[..., 2] = sin_elevation
        origins = np.empty(directions.shape)
        origins[...] = row_origins[None, :, None, :]
    if sensor.pitch_deg:
        directions = _pitch(directions, sensor.pitch_deg)
    return origins, directions
