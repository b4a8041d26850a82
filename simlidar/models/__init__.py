"""Spiking (time-to-first-spike) and conventional networks, the model registry and the training
configuration."""
