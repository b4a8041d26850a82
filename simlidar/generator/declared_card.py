"""The card (``README.md``), ``croissant.json``, preview and checksums of a dataset whose
source is declared as a :class:`simlidar.dataset.source.Source` (converted real data, the
generator's pulse streams), made from its split files and that declaration; and the attributes
every such split carries (:func:`converted_split_attrs`).

The generator's datasets get theirs from :mod:`simlidar.release.card` and
:mod:`simlidar.release.croissant`; the table and Croissant helpers are shared with them.
"""

import json
from pathlib import Path

import h5py
import numpy as np

from simlidar import __version__
from simlidar.dataset.reader import dataset_splits
from simlidar.dataset.schema import CONVERTED_SCHEMAS, SPLITS
from simlidar.dataset.version import CONVERTED, SOURCES, notes_until
from simlidar.generator.about import CITATION
from simlidar.generator.pulses import NO_RETURN
from simlidar.release.card import (
    card_head,
    class_table,
    hf_feature,
    hf_front_matter,
    table,
    write_card,
)
from simlidar.release.checksums import write_sums
from simlidar.release.croissant import CONTEXT, field, file_objects, write_croissant
from simlidar.release.info import dataset_info
from simlidar.release.preview import write_preview


def _shape(shape: tuple, info) -> tuple:
    """A declared shape with a split's sizes: H rows, W columns, R rotations (a stream's)."""
    sizes = {"H": info.height, "W": info.width, "R": info.attrs.get("rotations")}
    return tuple(sizes.get(d, d) for d in shape)


def _shape_text(shape: tuple, info) -> str:
    return str(_shape(shape, info)).replace("'", "")


def _source_rows(splits: dict) -> list[list]:
    """The card's summary rows that only some sources have."""
    attrs = splits["train"].attrs
    rows = []
    if "tof_max_ns" in attrs:
        rows.append(["`tof_max_ns`", f"{attrs['tof_max_ns']:.3f} ns: the delay 1.0"])
    if "simulated_from" in attrs:
        sim = attrs["simulated_from"]
        rows.append(
            [
                "simulated",
                f"yes: the frames of simlidar sweep `{sim['sweep']}` ({sim['sensor_model']}), "
                "exported in the KITTI layout; not recorded data",
            ]
        )
    if "time_window_us" in attrs:
        rows.append(["`time_window_us`", f"{attrs['time_window_us']:g} us: the delay 1.0"])
    if "frame" in CONVERTED_SCHEMAS[splits["train"].source]:
        frames = {s: len(set(i.read(("frame",))["frame"])) for s, i in splits.items()}
        empty = len(attrs.get("frames_without_objects", []))
        rows.append(
            [
                "frames",
                ", ".join(f"{s} {n}" for s, n in frames.items())
                + f" ({empty} without objects, in neither)",
            ]
        )
    return rows


def _schema(info) -> dict:
    """The datasets a converted split holds (its source's, a receiver's too where it has one)."""
    return CONVERTED[info.source].schema_of("receiver" in info.attrs)


def converted_front_matter(path: Path) -> dict:
    """The YAML front matter (Hugging Face dataset card metadata) of a converted dataset."""
    splits = dataset_splits(path)
    info = splits["train"]
    about = CONVERTED[info.source].about_of("receiver" in info.attrs)
    features = [
        hf_feature(name, dtype, _shape(shape, info)[1:], info.attrs["class_names"])
        for name, (dtype, shape) in _schema(info).items()
        if shape[0] == "N"  # per-event datasets are not features of a sample
    ]
    pretty = f"{about.name}, {len(info.attrs['class_names'])} classes"
    return hf_front_matter(splits, features, about.license, pretty, about.tags, "default")


def regenerate_call(source: str, config: dict) -> str:
    """The Python call that converts the same input into the same bytes."""
    module, function, first = CONVERTED[source].call
    args = ", ".join(f"{k}={tuple(v) if isinstance(v, list) else v!r}" for k, v in config.items())
    given = "" if first is None else f"{first!r}, "
    return f"from {module} import {function}\n{function}({given}'data', {args})"


def converted_card(path: str | Path) -> str:
    """The whole card of a converted dataset directory, from its files alone."""
    path = Path(path)
    splits = dataset_splits(path)
    info = splits["train"]
    attrs = info.attrs
    about = CONVERTED[info.source].about_of("receiver" in attrs)
    names = attrs["class_names"]
    counts = dataset_info(path)["counts"]
    version = attrs["dataset_version"]
    _, dates, notes = SOURCES[info.source]
    lines = CONVERTED[info.source].fields_of("receiver" in attrs)
    sample = f"{info.height} x {info.width} float32 delays in [0, 1]"
    sections = [
        *card_head(
            path,
            converted_front_matter(path),
            f"{about.name}: {len(names)} classes",
            about.description,
        ),
        table(
            ["", ""],
            [
                ["source", f"`{info.source}` (input sha256 `{attrs['input_sha256']}`)"],
                ["dataset version", version],
                ["simlidar version", attrs["simlidar_version"]],
                ["classes", f"{len(names)} ({attrs['class_mode']})"],
                ["samples", ", ".join(f"{s} {i.size}" for s, i in splits.items())],
                ["sample", sample],
                ["seed", attrs["seed"]],
                *_source_rows(splits),
            ],
        )
        + "\n",
        "## Composition\n",
        f"What a value means: {about.delay_meaning}\n",
        class_table(names, splits, counts),
        "Each split file holds these datasets (N samples, E events):\n",
        table(
            ["dataset", "dtype", "shape", "meaning"],
            [
                [f"`{name}`", dtype, _shape_text(shape, info), lines[name]]
                for name, (dtype, shape) in _schema(info).items()
            ],
        )
        + "\n",
        f"## Conversion\n\n{about.conversion}\n",
        table(["parameter", "value"], [[f"`{k}`", v] for k, v in attrs["config"].items()]) + "\n",
        table(["sensor", "value"], [[f"`{k}`", v] for k, v in attrs["sensor"].items()]) + "\n",
        f"## Uses\n\n{about.uses}\n\n### Out-of-scope uses\n\n{about.out_of_scope}\n",
        f"## License\n\nThe source data's: `{about.license}` ({about.license_url}); source: "
        f"{about.homepage}.\n",
        "## Regenerate\n",
        f"With simlidar {attrs['simlidar_version']} (dataset version {version}) and the same "
        "input (its sha256 above):\n",
        "```python\n" + regenerate_call(info.source, attrs["config"]) + "\n```\n",
        "## Versions\n",
        "\n".join(
            f"* {v} ({dates.get(v, 'unreleased')}): {n}"
            # its own version's and those before it (CARD_NOTES_SINCE is the generator's:
            # a declared source's cards always listed those it knew, its own version's last)
            for v, n in notes_until(notes, version, version).items()
        )
        + "\n",
        "## Loading\n",
        "```python\nfrom simlidar.data import load_split\n"
        f"x, y = load_split('.', 'train')  # x: (N, {info.height}, {info.width}) float32, "
        "y: (N,) int64\n```\n",
        "## Citation\n\nPlease cite the source data and the paper whose pipeline this follows:\n",
        f"```bibtex\n{about.source_citation}\n\n{CITATION}\n```\n",
    ]
    return "\n".join(s for s in sections if s)


def converted_croissant(path: str | Path, name: str | None = None) -> dict:
    """The Croissant 1.0 description of a converted dataset directory."""
    path = Path(path)
    splits = dataset_splits(path)
    info = splits["train"]
    about = CONVERTED[info.source].about_of("receiver" in info.attrs)
    version = info.attrs["dataset_version"]
    schema = _schema(info)

    def record_set(split: str, rows: str) -> dict:
        fields = [n for n, (_, shape) in schema.items() if shape[0] == rows]
        what = "samples" if rows == "N" else "events"
        set_id = split if rows == "N" else f"{split}_events"
        return {
            "@type": "cr:RecordSet",
            "@id": set_id,
            "name": set_id,
            "description": f"The {what} of the {split} split, one record per row.",
            "field": [
                field(
                    set_id,
                    split,
                    n,
                    schema[n][0],
                    _shape(schema[n][1], info),
                    CONVERTED[info.source].fields_of("receiver" in info.attrs)[n],
                    sharded=info.sharded,
                )
                for n in fields
            ],
        }

    rows = sorted({shape[0] for _, shape in schema.values()}, key="NE".index)
    return {
        "@context": CONTEXT,
        "@type": "sc:Dataset",
        "conformsTo": "http://mlcommons.org/croissant/1.0",
        "name": name or path.name,
        "alternateName": about.name,
        "description": about.description,
        "license": about.license_url,
        "url": about.homepage,
        "creator": {"@type": "sc:Organization", "name": "simlidar developers"},
        "datePublished": SOURCES[info.source][1].get(version, "1970-01-01"),
        "version": version,
        "citeAs": about.source_citation,
        "keywords": list(about.tags),
        "distribution": file_objects(splits, "HDF5"),
        "recordSet": [record_set(s, r) for s in SPLITS for r in rows],
    }


def write_release_files(path: Path, name: str, preview: bool = True) -> None:
    """Preview, ``croissant.json``, card and ``SHA256SUMS`` of a dataset whose splits exist."""
    if preview:
        write_preview(path, path / "preview.png", title=name)
    write_croissant(path, converted_croissant(path, name))
    write_card(path, converted_card(path))
    write_sums(path)


def converted_split_attrs(
    source: str,
    split: str,
    config,
    class_names: tuple[str, ...],
    class_mode: str,
    sensor: dict,
    input_sha256: str,
) -> dict:
    """The attributes every converted split carries (``docs/converters.md``); a converter adds
    its own (``tof_max_ns``, ``time_window_us``, ...).

    source : the converter's source (``kitti``, ``dvs-barrel``), a key of
        :data:`simlidar.dataset.version.SOURCES`, which gives the dataset version
    split : ``train`` or ``test``
    config : the converter's configuration (:class:`~simlidar.convert.config.KittiConfig`,
        :class:`~simlidar.convert.config.DvsConfig`), stored as JSON with its seed
    class_names : the class names, in label order
    class_mode : what a class is (``object``, ``character``)
    sensor : what recorded the data (its name, resolution, range or time unit), stored as JSON
    input_sha256 : sha256 of the input (of what, per source: ``docs/converters.md``)
    """
    strings = h5py.string_dtype()
    return {
        "dataset_version": SOURCES[source][0],
        "simlidar_version": __version__,
        "source": source,
        "split": split,
        "config": config.to_json(),
        "seed": config.seed,
        "noise": 0.0,
        "classes": len(class_names),
        "class_mode": class_mode,
        "class_names": np.array(class_names, dtype=strings),
        "sensor": json.dumps(sensor, sort_keys=True),
        "no_return_delay": NO_RETURN,
        "input_sha256": input_sha256,
    }
