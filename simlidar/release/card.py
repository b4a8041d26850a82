"""The dataset card (``README.md``) of any dataset directory: Hugging Face front matter and
tables. What a card says comes from its source: :mod:`simlidar.generator.card` for the
generator's datasets, :mod:`simlidar.convert.card` for converted data, and
:func:`simlidar.sources.render_card` picks by the splits' ``source``."""

import json
from pathlib import Path

import yaml

from simlidar.dataset.schema import SPLITS
from simlidar.errors import DatasetError
from simlidar.release.checksums import write_text

CARD = "README.md"


def _size_category(n: int) -> str:
    for limit, name in (
        (1_000, "n<1K"),
        (10_000, "1K<n<10K"),
        (100_000, "10K<n<100K"),
        (1_000_000, "100K<n<1M"),
    ):
        if n < limit:
            return name
    return "n>1M"


def hf_feature(name: str, dtype: str, shape: tuple, class_names) -> dict:
    """One Hugging Face ``features`` entry of a per-sample dataset; shape without N."""
    if name == "labels":
        names = {str(k): n for k, n in enumerate(class_names)}
        return {"name": name, "dtype": {"class_label": {"names": names}}}
    if len(shape) == 2:
        return {"name": name, "array2_d": {"shape": list(shape), "dtype": dtype}}
    if shape:
        return {"name": name, "sequence": dtype, "length": shape[0]}
    return {"name": name, "dtype": dtype}


def data_files(split: str, info) -> str:
    """The card's ``data_files`` path of a split: its file, or a pattern of its shards."""
    return f"{split}-*.h5" if info.sharded else f"{split}.h5"


def hf_front_matter(
    splits: dict,
    features: list[dict],
    license: str,
    pretty_name: str,
    tags: list[str],
    config_name: str,
) -> dict:
    """The Hugging Face card metadata of a dataset directory's splits (generated or converted)."""
    nbytes = {s: info.nbytes for s, info in splits.items()}
    return {
        "license": license,
        "pretty_name": pretty_name,
        "task_categories": ["image-classification"],
        "size_categories": [_size_category(sum(i.size for i in splits.values()))],
        "tags": list(tags),
        "configs": [
            {
                "config_name": config_name,
                "data_files": [{"split": s, "path": data_files(s, splits[s])} for s in SPLITS],
            }
        ],
        "dataset_info": {
            "config_name": config_name,
            "features": features,
            "splits": [
                {"name": s, "num_bytes": nbytes[s], "num_examples": splits[s].size} for s in SPLITS
            ],
            "download_size": sum(nbytes.values()),  # the split files
            "dataset_size": sum(nbytes.values()),
        },
    }


def table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def class_table(names: list[str], splits, counts: dict) -> str:
    """A card's table of classes: index, name and its samples in each of ``splits``
    (``counts``: split -> class name -> count, as ``simlidar info`` gives them)."""
    rows = [[k, name, *(counts[s][name] for s in splits)] for k, name in enumerate(names)]
    return table(["class", "name", *splits], rows) + "\n"


def front_matter_block(meta: dict) -> str:
    """The card's first lines: ``meta`` as YAML between ``---`` lines."""
    return f"---\n{yaml.safe_dump(meta, sort_keys=False, allow_unicode=True, width=1000)}---\n"


def write_card(path: str | Path, text: str) -> Path:
    """(Re)write ``README.md`` of a dataset directory with ``text`` (replaced, never written
    through a link)."""
    return write_text(Path(path) / CARD, text)


def read_front_matter(path: str | Path) -> dict:
    """The YAML front matter of a dataset's card; DatasetError when missing or malformed."""
    card = Path(path) / CARD
    if not card.is_file():
        raise DatasetError(f"{card}: missing (expected the dataset card)")
    try:
        text = card.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        message = f"{card}: not UTF-8 text ({exc.reason} at byte {exc.start})"
        raise DatasetError(f"{message}; expected the dataset card in UTF-8") from None
    if not text.startswith("---\n") or "\n---\n" not in text[3:]:
        raise DatasetError(f"{card}: expected YAML front matter between '---' lines at the top")
    try:
        meta = yaml.safe_load(text[4 : text.index("\n---\n", 3)])
    except yaml.YAMLError as exc:
        message = f"{card}: malformed YAML front matter ({exc})".replace("\n", " ")
        raise DatasetError(message) from None
    if not isinstance(meta, dict) or "dataset_info" not in meta:
        raise DatasetError(f"{card}: front matter without dataset_info")
    return json.loads(json.dumps(meta))  # plain types only
