"""Whether a dataset directory already under a requested name is the dataset a ``generate``
request would write, so that the request keeps it instead of stopping (``generate --noise
0.1,0.2,0.33,0.5`` after the quick start made the 0.2 one)."""

import json
from pathlib import Path

from simlidar.dataset.reader import read_split
from simlidar.dataset.schema import SPLITS
from simlidar.dataset.shards import find_split_files
from simlidar.dataset.version import dataset_version
from simlidar.errors import DatasetError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.shard import split_shards
from simlidar.scene.recipe import Catalog


def differs(
    path: Path, config: GeneratorConfig, catalog: Catalog, shard_samples: int, preview: bool
) -> str | None:
    """Why the dataset directory ``path`` is not the one ``config`` writes there (the words
    after "already exists and"), or None where it is: each split's files those the request
    writes (``shard_samples``), its configuration, version and scene catalog (``catalog``, the
    sensor's part) the request's, a ``preview.png`` where ``preview`` asks for one, and
    ``simlidar verify`` finding nothing wrong (checksums included)."""
    from simlidar.release.verify import verify

    if path.is_symlink() or not path.is_dir():
        return "is not a dataset directory (a file, or a link)"
    names = {shard.name for shard in split_shards(config, shard_samples)}
    try:
        found = {p.name for split in SPLITS for p in find_split_files(path, split)}
        if found != names:
            return f"holds the split files {sorted(found)}, not {sorted(names)}"
        attrs = [read_split(path, split).attrs for split in SPLITS]
    except (DatasetError, OSError) as exc:
        return f"is not a dataset simlidar reads ({exc})"
    want = json.loads(config.to_json())
    for got in attrs:
        if got.get("config") != want:
            return "was made with another configuration"
        if got.get("dataset_version") != dataset_version(config):
            return f"is of dataset version {got.get('dataset_version')}"
        if got.get("catalog_sha256") != catalog.fingerprint():
            return "was made from another scene catalog"
    if preview and not (path / "preview.png").is_file():
        return "has no preview.png"
    problems = verify(path)
    if problems:
        return f"does not verify ({problems[0]})"
    return None
