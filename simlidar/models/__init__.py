"""Spiking (time-to-first-spike) layers and networks, and the model registry."""

from simlidar.models import networks  # noqa: F401  (registers the models)
