"""Every source of datasets, by the name a split's ``source`` attribute holds: the generator
and the converters. What only needs one of them imports it; what takes any dataset directory
(``simlidar card``) comes here."""

from pathlib import Path

from simlidar.dataset.reader import dataset_splits
from simlidar.dataset.version import GENERATOR
from simlidar.errors import DatasetError
from simlidar.generator.declared_card import converted_card
from simlidar.generator.generated_card import generated_card
from simlidar.release.card import CARD, write_card
from simlidar.release.checksums import SUMS, read_sums, write_sums


def render_card(path: str | Path) -> str:
    """The whole card of any dataset directory, from its files alone."""
    if dataset_splits(path)["train"].source == GENERATOR:
        return generated_card(path)
    return converted_card(path)


def rewrite_card(path: str | Path) -> Path:
    """``simlidar card``: rewrite the card of any dataset directory from its files, and its
    line in SHA256SUMS when there is one. Refused before anything is written when the card or
    SHA256SUMS is a link (a file of the dataset is replaced, never written through) or
    SHA256SUMS is malformed."""
    path = Path(path)
    dataset_splits(path)  # a dataset, or a one-line error
    for name in (CARD, SUMS):
        if (path / name).is_symlink() or ((path / name).exists() and not (path / name).is_file()):
            raise DatasetError(
                f"{path / name}: is not a regular file (a link or a folder); expected the "
                "dataset's own file: remove it and run simlidar card again"
            )
    sums = (path / SUMS).exists()
    if sums:
        try:
            read_sums(path)
        except ValueError as exc:
            raise DatasetError(f"{exc}; nothing written (simlidar verify names the rest)") from None
    written = write_card(path, render_card(path))
    if sums:
        write_sums(path, [CARD])
    return written
