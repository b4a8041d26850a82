"""``simlidar convert kitti`` and ``convert dvs-barrel``: real data into the schema."""

import json
from functools import partial
from pathlib import Path

import click

from simlidar.cli.options import DEFAULT_OUT, FiniteRange, IntegerRange, setting_option
from simlidar.convert.config import DvsConfig, KittiConfig


@click.group()
def convert():
    """Convert real data into the simlidar schema (KITTI front view, DVS barrel events)."""


def _converted(path: Path, as_json: bool) -> None:
    from simlidar.dataset.reader import dataset_splits

    splits = dataset_splits(path)
    sizes = {name: info.size for name, info in splits.items()}
    if as_json:
        click.echo(json.dumps({"path": str(path), "splits": sizes}))
    else:
        click.echo(f"wrote {path} (train {sizes['train']}, test {sizes['test']})")


def _convert_options(config, command):
    """--out, --seed (the split's, from ``config``), --force and --json."""
    for option in reversed(
        [
            click.option(
                "--out",
                type=click.Path(file_okay=False, path_type=Path),
                default=DEFAULT_OUT,
                show_default=True,
                help="Folder for the dataset directory.",
            ),
            setting_option(config, "seed"),
            click.option(
                "--force", is_flag=True, help="Replace an existing dataset of the same name."
            ),
            click.option(
                "--json", "as_json", is_flag=True, help="Print one JSON object on stdout."
            ),
        ]
    ):
        command = option(command)
    return command


@convert.command("kitti")
@click.argument("root", type=click.Path(path_type=Path))
@setting_option(KittiConfig, "crop", type=(IntegerRange(1, 4096), IntegerRange(1, 4096)))
@setting_option(KittiConfig, "res_h_deg", "--res-h", "res_h")
@setting_option(KittiConfig, "res_v_deg", "--res-v", "res_v")
@setting_option(KittiConfig, "max_range_m", "--max-range", "max_range")
@setting_option(KittiConfig, "test_fraction")
@partial(_convert_options, KittiConfig)
def convert_kitti(root, crop, res_h, res_v, max_range, test_fraction, out, seed, force, as_json):
    """KITTI 3D object benchmark (ROOT: training/ with velodyne/, label_2/, calib/, or its
    parent) -> front-view pulse crops around every labelled object, 8 classes, split by frame.
    See docs/converters.md."""
    from simlidar.convert import convert_kitti as run

    # the options as the converter's keywords (generate passes its own to GeneratorConfig)
    path = run(
        root,
        out,
        crop=crop,
        res_h_deg=res_h,
        res_v_deg=res_v,
        max_range_m=max_range,
        test_fraction=test_fraction,
        seed=seed,
        force=force,
        progress=not as_json,
    )
    _converted(path, as_json)


@convert.command("dvs-barrel")
@click.argument("mat_file", type=click.Path(path_type=Path))
@setting_option(DvsConfig, "labels")
@setting_option(DvsConfig, "window_us", type=FiniteRange(0, None, min_open=True))
@setting_option(DvsConfig, "address_base")
@setting_option(DvsConfig, "test_fraction")
@partial(_convert_options, DvsConfig)
def convert_dvs(
    mat_file, labels, window_us, address_base, test_fraction, out, seed, force, as_json
):
    """DVS barrel MATLAB file (struct array ROI: x, y, polarity, timestamps in us; 32 x 32
    pixels, 36 characters) -> first-spike times per pixel, raw events kept alongside. See
    docs/converters.md."""
    from simlidar.convert import convert_dvs_barrel as run

    path = run(
        mat_file,
        out,
        labels=tuple(labels) if labels else None,
        window_us=window_us,
        address_base=int(address_base),
        test_fraction=test_fraction,
        seed=seed,
        force=force,
        progress=not as_json,
    )
    _converted(path, as_json)
