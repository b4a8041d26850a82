"""The dataset card (``README.md``) of any dataset directory: Hugging Face front matter and
tables. What a card says comes from its source: :mod:`simlidar.generator.generated_card` for the
generator's datasets, :mod:`simlidar.generator.declared_card` for converted data, and
:func:`simlidar.any_card.render_card` picks by the splits' ``source``."""

import json
from pathlib import Path

import yaml

from simlidar.content import read_text
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
    if len(shape) in (2, 3):  # Hugging Face's Array2D, Array3D
        kind = f"array{len(shape)}_d"
        return {"name": name, kind: {"shape": list(shape), "dtype": dtype}}
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
    """The Hugging Face card metadata of a dataset directory's splits (generated or converted).

    splits : split name -> its :class:`~simlidar.dataset.reader.SplitInfo`, every one of
        ``SPLITS`` (:func:`~simlidar.dataset.reader.dataset_splits`): their files, samples and
        bytes on disk
    features : a sample's ``features`` entries (:func:`hf_feature`)
    license : the data's Hugging Face license id (``cc-by-4.0`` for the generated data)
    pretty_name : the dataset's title
    tags : the card's tags
    config_name : the name of the dataset's one config (``noise0.2``, ``default``)
    returns : the front matter as a dict, for :func:`front_matter_block`
    """
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


def card_head(path: str | Path, meta: dict, title: str, description: str) -> list[str]:
    """The first sections of a dataset directory's card: the front matter (``meta``), the
    title, the preview if the directory has one, and the description."""
    preview = Path(path) / "preview.png"
    return [
        front_matter_block(meta),
        f"# {title}\n",
        "![one example per class (test split)](preview.png)\n" if preview.exists() else "",
        f"{description}\n",
    ]


def write_card(path: str | Path, text: str) -> Path:
    """(Re)write ``README.md`` of a dataset directory with ``text`` (replaced, never written
    through a link)."""
    return write_text(Path(path) / CARD, text)


# A card is a few KB (a 32-class generated one: about 12 KB); no more than this is ever read, so
# that a 3 GB (sparse) README.md is one line instead of 3 GB in memory
MAX_CARD_BYTES = 4 * 2**20
# The front matter nests 8 levels deep (dataset_info.features[].dtype.class_label.names); deeper
# than this is refused before PyYAML's composer recurses (20,000 levels: a RecursionError)
MAX_FRONT_MATTER_DEPTH = 64


class _Refused(Exception):
    """What the card's YAML may not hold: the reason, with its line."""


class _CardLoader(yaml.SafeLoader):
    """PyYAML's safe loader without anchors and aliases (nine levels of aliases, a "billion
    laughs", expand to gigabytes) and with nesting bounded by :data:`MAX_FRONT_MATTER_DEPTH`;
    both checked on the event stream, before any node is built."""

    depth = 0

    def compose_node(self, parent, index):
        event = self.peek_event()
        line = event.start_mark.line + 1 if event.start_mark else "?"
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            raise _Refused(
                f"YAML anchor or alias ('&' or '*') at line {line}; expected plain YAML without "
                "anchors or aliases"
            )
        self.depth += 1
        try:
            if self.depth > MAX_FRONT_MATTER_DEPTH:
                raise _Refused(
                    f"nested deeper than {MAX_FRONT_MATTER_DEPTH} levels at line {line}; "
                    f"expected at most {MAX_FRONT_MATTER_DEPTH}"
                )
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1


def read_front_matter(path: str | Path) -> dict:
    """The YAML front matter of a dataset's card; DatasetError when missing or malformed. At most
    :data:`MAX_CARD_BYTES` are read (of a regular file: never a pipe or a device), and the YAML
    may hold no anchors or aliases and nest at most :data:`MAX_FRONT_MATTER_DEPTH` deep."""
    card = Path(path) / CARD
    if not card.exists() and not card.is_symlink():
        raise DatasetError(f"{card}: missing (expected the dataset card)")
    text = read_text(card, MAX_CARD_BYTES, DatasetError)
    if not text.startswith("---\n") or "\n---\n" not in text[3:]:
        raise DatasetError(f"{card}: expected YAML front matter between '---' lines at the top")
    try:
        meta = yaml.load(text[4 : text.index("\n---\n", 3)], Loader=_CardLoader)
    except _Refused as exc:
        raise DatasetError(f"{card}: front matter {exc}") from None
    except RecursionError:
        raise DatasetError(f"{card}: front matter nested too deeply; expected plain YAML") from None
    except yaml.YAMLError as exc:
        message = f"{card}: malformed YAML front matter ({exc})".replace("\n", " ")
        raise DatasetError(message) from None
    if not isinstance(meta, dict) or "dataset_info" not in meta:
        raise DatasetError(f"{card}: front matter without dataset_info")
    return json.loads(json.dumps(meta))  # plain types only
