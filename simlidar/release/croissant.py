"""``croissant.json``: Croissant 1.0 metadata (JSON-LD) of a dataset directory."""

import json
from pathlib import Path

from simlidar.atomic import write_file
from simlidar.dataset.schema import SPLITS
from simlidar.release.checksums import sha256_file

CROISSANT = "croissant.json"
# The JSON-LD @context of Croissant 1.0, as the specification gives it.
CONTEXT = {
    "@language": "en",
    "@vocab": "https://schema.org/",
    "citeAs": "cr:citeAs",
    "column": "cr:column",
    "conformsTo": "dct:conformsTo",
    "cr": "http://mlcommons.org/croissant/",
    "rai": "http://mlcommons.org/croissant/RAI/",
    "data": {"@id": "cr:data", "@type": "@json"},
    "dataType": {"@id": "cr:dataType", "@type": "@vocab"},
    "dct": "http://purl.org/dc/terms/",
    "equivalentProperty": "cr:equivalentProperty",
    "examples": {"@id": "cr:examples", "@type": "@json"},
    "extract": "cr:extract",
    "field": "cr:field",
    "fileProperty": "cr:fileProperty",
    "fileObject": "cr:fileObject",
    "fileSet": "cr:fileSet",
    "format": "cr:format",
    "includes": "cr:includes",
    "isLiveDataset": "cr:isLiveDataset",
    "jsonPath": "cr:jsonPath",
    "key": "cr:key",
    "md5": "cr:md5",
    "parentField": "cr:parentField",
    "path": "cr:path",
    "recordSet": "cr:recordSet",
    "references": "cr:references",
    "regex": "cr:regex",
    "repeated": "cr:repeated",
    "replace": "cr:replace",
    "samplingRate": "cr:samplingRate",
    "sc": "https://schema.org/",
    "separator": "cr:separator",
    "source": "cr:source",
    "subField": "cr:subField",
    "transform": "cr:transform",
}
DATA_TYPES = {
    "float32": "sc:Float",
    "float64": "sc:Float",
    "int64": "sc:Integer",
    "int32": "sc:Integer",
    "uint8": "sc:Integer",
    "uint16": "sc:Integer",
    "int8": "sc:Integer",
}


def file_objects(splits: dict, kind: str) -> list[dict]:
    """The Croissant distribution of a dataset's splits: a FileObject (with its sha256) for a
    one-file split, a FileSet (``includes``: the shards' pattern) for a sharded one, whose
    files' checksums are in SHA256SUMS."""
    objects = []
    for split in SPLITS:
        info = splits[split]
        if info.sharded:
            objects.append(
                {
                    "@type": "cr:FileSet",
                    "@id": f"{split}-*.h5",
                    "name": f"{split}-*.h5",
                    "description": f"The {split} split ({kind}) in {len(info.files)} shard "
                    f"files of {info.sizes[0]} samples (the last: {info.sizes[-1]}), in order.",
                    "encodingFormat": "application/x-hdf5",
                    "includes": f"{split}-*.h5",
                }
            )
            continue
        objects.append(
            {
                "@type": "cr:FileObject",
                "@id": f"{split}.h5",
                "name": f"{split}.h5",
                "description": f"The {split} split ({kind}).",
                "contentUrl": f"{split}.h5",
                "contentSize": f"{info.path.stat().st_size} B",
                "encodingFormat": "application/x-hdf5",
                "sha256": sha256_file(info.path),
            }
        )
    return objects


def field(
    record_set: str,
    split: str,
    name: str,
    dtype: str,
    shape: tuple,
    doc: str | None = None,
    sharded: bool = False,
) -> dict:
    """A Croissant Field: column ``name`` of ``split``.h5 (or of its shards), of ``dtype`` and
    ``shape``.

    record_set : the @id of the RecordSet that holds the field (its own @id is
        ``record_set/name``)
    dtype, shape : a key of :data:`DATA_TYPES` and the dataset's full shape, sizes that vary
        as letters (``("N", 16, 118)``), both written into the description
    doc : what the column holds, appended to the description (None: nothing)
    sharded : whether the split is written as shard files (the source is then the FileSet
        ``split-*.h5``, else the FileObject ``split.h5``)
    """
    shape_text = str(tuple(shape)).replace("'", "")
    source = (
        {"fileSet": {"@id": f"{split}-*.h5"}} if sharded else {"fileObject": {"@id": f"{split}.h5"}}
    )
    return {
        "@type": "cr:Field",
        "@id": f"{record_set}/{name}",
        "name": name,
        "description": f"HDF5 dataset `{name}`, {dtype} {shape_text}" + (f": {doc}" if doc else ""),
        "dataType": DATA_TYPES[dtype],
        "source": source | {"extract": {"column": name}},
    }


def write_croissant(path: str | Path, document: dict) -> Path:
    """(Re)write ``croissant.json`` of a dataset directory."""
    text = json.dumps(document, indent=2) + "\n"
    return write_file(Path(path) / CROISSANT, lambda tmp: tmp.write_text(text))
