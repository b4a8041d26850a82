"""``simlidar info``, ``preview``, ``card``, ``verify``, ``pack`` and ``fetch``: a finished
dataset directory, checked, described and published."""

import json
import sys
from pathlib import Path

import click

from simlidar.cli.options import (
    DEFAULT_OUT,
    FiniteRange,
    OutFolder,
)
from simlidar.release.archive import MAX_TIMEOUT_S, TIMEOUT_S
from simlidar.release.archive import fetch as fetch_dataset
from simlidar.release.archive import pack as pack_dataset


@click.command()
@click.argument("path", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
def info(path, as_json):
    """Show a dataset's versions, classes, counts per split and class, noise and config."""
    from simlidar.release.info import dataset_info, format_info

    summary = dataset_info(path)
    if as_json:
        click.echo(json.dumps(summary))
        return
    click.echo(format_info(summary))


@click.command()
@click.argument("path", type=click.Path(path_type=Path))
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="PNG file to write.",
)
@click.option("--split", type=click.Choice(["train", "test"]), default="test", show_default=True)
def preview(path, out, split):
    """Draw one example per class (delays as grey levels) into a PNG file."""
    from simlidar.errors import DatasetError
    from simlidar.release.preview import write_preview

    if out.suffix.lower() != ".png":
        raise click.BadParameter(
            f"{out}: expected a file name ending in .png", param_hint="'--out'"
        )
    if not out.parent.is_dir():
        raise DatasetError(f"--out {out}: folder {out.parent} does not exist")
    click.echo(f"wrote {write_preview(path, out, split)}")


@click.command()
@click.argument("path", type=click.Path(path_type=Path))
def card(path):
    """Rewrite a dataset's card (README.md) from its files, and its line in SHA256SUMS."""
    from simlidar.any_card import rewrite_card

    click.echo(f"wrote {rewrite_card(path)}")


@click.command()
@click.argument("path", type=click.Path(path_type=Path))
def verify(path):
    """Check a dataset: checksums, HDF5 schema, value ranges, split sizes against the card."""
    from simlidar.dataset.reader import dataset_splits
    from simlidar.release.verify import verify as run

    problems = run(path)
    if problems:
        for problem in problems:
            click.echo(f"FAILED {problem}", err=True)
        click.echo(f"{path}: {len(problems)} problem(s)", err=True)
        sys.exit(1)
    splits = dataset_splits(path)
    sizes = ", ".join(f"{s} {info.size}" for s, info in splits.items())
    version = splits["train"].attrs["dataset_version"]
    click.echo(
        f"{path}: OK (dataset version {version}, {sizes}; checksums, schema, value "
        "ranges and card agree)"
    )


@click.command()
@click.argument("path", type=click.Path(path_type=Path))
@click.option(
    "--out",
    type=OutFolder(),
    default=None,
    help="Folder for the archive (default: beside the dataset).",
)
def pack(path, out):
    """Verify a dataset and write <name>.tar.gz and its .sha256, ready to upload."""

    archive, checksum = pack_dataset(path, out)
    click.echo(f"wrote {archive} and {checksum.name}")


def _hex_sha256(ctx, param, value):
    """--sha256 must be 64 hexadecimal digits (usage error otherwise)."""
    from simlidar.release.checksums import is_sha256

    if value is not None and not is_sha256(value):
        raise click.BadParameter(f"{value!r}: expected 64 hexadecimal digits")
    return value


@click.command()
@click.argument("url")
@click.option(
    "--sha256",
    default=None,
    metavar="HEX",
    callback=_hex_sha256,
    help="Expected sha256 of the archive (default: read from URL.sha256).",
)
@click.option("--out", type=OutFolder(), default=DEFAULT_OUT, show_default=True)
@click.option(
    "--timeout",
    type=FiniteRange(0.1, MAX_TIMEOUT_S),
    default=TIMEOUT_S,
    show_default=True,
    help="Seconds to wait for the server (at most a day).",
)
@click.option("--force", is_flag=True, help="Replace an existing dataset of the same name.")
def fetch(url, sha256, out, timeout, force):
    """Download a dataset archive, check it, extract it safely, verify it, install it."""

    click.echo(f"installed {fetch_dataset(url, sha256, out, timeout=timeout, force=force)}")
