"""Every source of datasets, by the name a split's ``source`` attribute holds: the generator
and the converters. What only needs one of them imports it; what takes any dataset directory
(``simlidar card``) comes here."""

from pathlib import Path

from simlidar.convert.card import converted_card
from simlidar.dataset.reader import dataset_splits
from simlidar.dataset.version import GENERATOR
from simlidar.generator.card import generated_card


def render_card(path: str | Path) -> str:
    """The whole card of any dataset directory, from its files alone."""
    if dataset_splits(path)["train"].source == GENERATOR:
        return generated_card(path)
    return converted_card(path)
