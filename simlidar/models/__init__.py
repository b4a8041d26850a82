"""Spiking (time-to-first-spike) and conventional networks, and the model registry."""

from simlidar.models import conventional, networks  # noqa: F401  (registers the models)
