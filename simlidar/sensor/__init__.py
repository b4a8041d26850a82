"""Sensor models (declarative files in ``sensors/``) and the batched ray caster."""

from simlidar.sensor.model import (
    DEFAULT_SENSOR,
    SPEED_OF_LIGHT_M_PER_S,
    Sensor,
    default_sensor,
    load_sensor,
    row_order,
    sensor_names,
    tof_ns,
)
from simlidar.sensor.rays import column_centres_deg, firing_azimuths_deg, window_rays

__all__ = [
    "DEFAULT_SENSOR",
    "SPEED_OF_LIGHT_M_PER_S",
    "Sensor",
    "column_centres_deg",
    "default_sensor",
    "firing_azimuths_deg",
    "load_sensor",
    "row_order",
    "sensor_names",
    "tof_ns",
    "window_rays",
]
