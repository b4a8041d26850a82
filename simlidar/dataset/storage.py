"""What an HDF5 file or a dataset directory from elsewhere holds, checked from its structure
before any of its data is read: links and hard links at any depth, where each dataset's bytes
are stored (in the file, every chunk written, no filter but the writers'), and directory
entries that are regular files. The schema's checks build on these
(:mod:`simlidar.dataset.reader`)."""

import math
import os
import stat
from pathlib import Path

import h5py

from simlidar.content import file_kind
from simlidar.dataset.schema import generated_schema
from simlidar.dataset.version import CONVERTED
from simlidar.errors import first_line
from simlidar.resources import size_text

# The most links a file from elsewhere may hold, at any depth: a split holds about 25 datasets
# at its root and a sweep's frames file about 20; a file of a million empty groups would make
# every reader walk them before it read a sample
MAX_LINKS = 1000


def datasets_of(path: Path, f: h5py.File) -> tuple[dict[str, h5py.Dataset], list[str]]:
    """The datasets at the root of an open HDF5 file by name, and the problems of every object
    in it, at any depth (other readers, Hugging Face ``datasets`` among them, walk groups):
    a soft or external link (which would read another file's data), an object under more than
    one name (a hard link: one field passed off as another), a dataset whose storage is not
    the writers' (:func:`storage_problem`), a group under a name the schemas use, and more
    than :data:`MAX_LINKS` links. Read from the file's structure alone, before any data."""
    datasets, problems, seen = {}, [], []
    names = set(generated_schema("scan", True, 2, 1, motion=True))
    names |= {n for s in CONVERTED.values() for n in s.schema_of(True)}

    def visit(name: str):
        seen.append(name)
        if len(seen) > MAX_LINKS:
            problems.append(
                f"{path}: more than {MAX_LINKS} HDF5 links; expected a split's few datasets"
            )
            return True  # stops the walk
        link = f.get(name, getlink=True)
        if not isinstance(link, h5py.HardLink):
            what = type(link).__name__  # SoftLink, ExternalLink, or a user-defined link
            problems.append(f"{path}: '{name}' is an HDF5 {what}, expected a dataset in the file")
            return None
        obj = f[name]
        links = h5py.h5o.get_info(obj.id).rc
        if links > 1:
            problems.append(
                f"{path}: '{name}' is one object under {links} names (an HDF5 hard link); "
                "expected each dataset under its own name"
            )
        if isinstance(obj, h5py.Dataset):
            problem = storage_problem(obj)
            if problem is not None:
                problems.append(f"{path}: {problem}")
            elif "/" not in name:
                datasets[name] = obj
        elif isinstance(obj, h5py.Group) and name in names:
            problems.append(f"{path}: '{name}' is a group, expected a dataset")
        return None

    try:
        f.visit_links(visit)
    except (OSError, RuntimeError, ValueError, TypeError, KeyError) as exc:
        problems.append(f"{path}: HDF5 structure unreadable ({first_line(exc)})")
    return datasets, problems


def check_storage(path: Path, f: h5py.File) -> list[str]:
    """The problems of an open HDF5 file's members (:func:`datasets_of`) and of every
    dataset's storage (:func:`storage_problem`): what a reader of a file from elsewhere (a
    split, a sweep's frames file) checks before reading any data."""
    datasets, problems = datasets_of(path, f)
    return problems + [f"{path}: {p}" for p in map(storage_problem, datasets.values()) if p]


# deflate (gzip) compresses at most about 1032 : 1 (long runs of one byte); the files this
# package writes stay far below it (labels about 40 : 1, surface labels about 10 : 1)
MAX_COMPRESSION = 1032


# The largest chunk a reader inflates, uncompressed: reading any row of a chunk decompresses
# all of it, so one gzip chunk of 1,048,576 samples (1 GiB) in a 3.5 MB file made verify take
# 1.26 GB. The largest chunk this package writes: 256 samples x 64 beams x 1024 columns x 8
# bytes = 128 MiB (the scan-timed `emission_ns` of an HDL-64E at the widest width generate
# takes); its defaults stay far below (a VLP-16 split, 16 x 16: 256 KiB of delays; scan-timed
# HDL-64E, 64 x 16: 2 MiB; a KITTI crop of 50 x 118: 5.8 MiB; DVS 32 x 32: 1 MiB, its events in
# chunks of 65,536 rows: 512 KiB; a sweep frame of the HDL-64E, 64 x 2083: 0.5 MiB).
MAX_CHUNK_BYTES = 128 * 2**20
# The only filters the writers use (gzip and shuffle); any other (a plugin, scale-offset, ...)
# is refused before HDF5 looks for it
FILTERS = {h5py.h5z.FILTER_DEFLATE: "gzip", h5py.h5z.FILTER_SHUFFLE: "shuffle"}
_LAYOUTS = {h5py.h5d.COMPACT: "compact", h5py.h5d.VIRTUAL: "virtual"}


def storage_problem(dataset: h5py.Dataset) -> str | None:
    """Why a dataset is not stored as the writers of this package store theirs, or None: in
    the file's own bytes, contiguous or in chunks (not in external files, a virtual dataset
    mapped from other files, or compact), with no filter but gzip and shuffle, chunks of at
    most :data:`MAX_CHUNK_BYTES` uncompressed, and every declared byte backed
    (:func:`unbacked`). Checked from the dataset's creation properties alone, before any of
    its data is read."""
    name = dataset.name.lstrip("/")
    expected = "expected a dataset whose bytes are in the file, contiguous or chunked"
    try:
        plist = dataset.id.get_create_plist()
        layout = plist.get_layout()
        externals = plist.get_external_count()
        if dataset.is_virtual or layout == h5py.h5d.VIRTUAL:
            return f"'{name}' is an HDF5 virtual dataset (mapped from other files); {expected}"
        if externals:
            file = plist.get_external(0)[0].decode(errors="replace")
            return f"'{name}' is stored in the external file {file!r}; {expected}"
        if layout not in (h5py.h5d.CONTIGUOUS, h5py.h5d.CHUNKED):
            kind = _LAYOUTS.get(layout, f"layout {layout}")
            return f"'{name}' has {kind} storage; {expected}"
        if layout == h5py.h5d.CHUNKED:
            for index in range(plist.get_nfilters()):
                code, _, _, label = plist.get_filter(index)
                if code not in FILTERS:
                    label = label.decode(errors="replace") or "unknown"
                    return (
                        f"'{name}' asks for HDF5 filter {code} ({label}); expected only "
                        f"{' and '.join(FILTERS.values())}"
                    )
            chunk = math.prod(dataset.chunks) * dataset.dtype.itemsize
            if chunk > MAX_CHUNK_BYTES:
                return (
                    f"'{name}' is stored in chunks of {dataset.chunks} {dataset.dtype} "
                    f"({size_text(chunk)} each); expected chunks of at most "
                    f"{size_text(MAX_CHUNK_BYTES)}"
                )
    except (OSError, RuntimeError, ValueError, TypeError) as exc:
        return f"'{name}': storage unreadable ({first_line(exc)})"
    return unbacked(dataset)


def unbacked(dataset: h5py.Dataset) -> str | None:
    """Why a dataset's declared size is not backed by bytes in its file, or None.

    A small file can declare millions of samples (an HDF5 "bomb": a chunked dataset whose
    chunks were never written reads as fill values), and reading it would allocate all that
    was declared. The writers of this package (:class:`~simlidar.dataset.writer.SplitWriter`)
    write every chunk, gzip-compressed; so a dataset is refused unless every chunk is stored
    (a contiguous one: all its bytes) and the declared bytes are at most
    :data:`MAX_COMPRESSION` times the stored ones.
    """
    declared = dataset.size * dataset.dtype.itemsize
    if declared == 0:
        return None
    stored = dataset.id.get_storage_size()
    if dataset.chunks is not None:
        chunks = math.prod(-(-n // c) for n, c in zip(dataset.shape, dataset.chunks))
        written = dataset.id.get_num_chunks()
        held = f" in {written} of {chunks} chunks"
        complete = written >= chunks and declared <= stored * MAX_COMPRESSION
    else:
        held, complete = "", stored >= declared
    if complete:
        return None
    return (
        f"'{dataset.name.lstrip('/')}' declares {dataset.shape} {dataset.dtype} "
        f"({size_text(declared)}) but stores {size_text(stored)}{held}; expected a dataset "
        "whose bytes are in the file (every chunk written)"
    )


def entry_problem(entry: Path) -> str | None:
    """Why an entry of a dataset directory is not a file of its own, or None: a regular file
    itself (``lstat``), never a link (it would be read, hashed and packed as the file it points
    to, a private one say), a folder, a pipe, a socket or a device. What verify says of every
    entry and every reader of each split file."""
    try:
        mode = entry.lstat().st_mode
    except OSError as exc:
        return f"{entry}: cannot be read ({exc.strerror}); expected a regular file"
    if stat.S_ISREG(mode):
        return None
    target = f" to {os.readlink(entry)}" if stat.S_ISLNK(mode) else ""
    return (
        f"{entry}: is {file_kind(mode)}{target}, expected a regular file (a dataset "
        "directory holds only its own files, listed in SHA256SUMS)"
    )
