"""The VLP-16 sensor model and the batched ray caster."""

from simlidar.sensor.rays import column_centres_deg, firing_azimuths_deg, window_rays
from simlidar.sensor.vlp16 import (
    ELEVATIONS_DEG,
    SPEED_OF_LIGHT_M_PER_S,
    VERTICAL_OFFSETS_MM,
    VLP16,
    row_order,
    tof_ns,
)

__all__ = [
    "ELEVATIONS_DEG",
    "SPEED_OF_LIGHT_M_PER_S",
    "VERTICAL_OFFSETS_MM",
    "VLP16",
    "column_centres_deg",
    "firing_azimuths_deg",
    "row_order",
    "tof_ns",
    "window_rays",
]
