"""A benchmark's output directory: who owns it (suite.json), its cells as written and read,
and results.json collected from them (the layout: :mod:`simlidar.bench.run`)."""

import json
import math
import os
import platform
import re
import shutil
from pathlib import Path

import torch

from simlidar import __version__
from simlidar.atomic import clean_stale, temporary_of, write_file
from simlidar.bench.cells import recorded_rules
from simlidar.bench.suite import Suite
from simlidar.content import content_dir, read_text
from simlidar.errors import DatasetError, ResultsError

_NUMBERS = re.compile(r"\[[-0-9.eE+,\s]*\]")  # a list of numbers spread over lines


def write_json(path: Path, data, indent: int | None = 1) -> None:
    """Write atomically; with ``indent``, lists of numbers stay on one line each. Strict JSON:
    a non-finite number (which Python would write as a bare ``Infinity``, which JSON parsers
    refuse) is refused in one line instead; the values are made finite where they come in."""
    try:
        text = json.dumps(data, indent=indent, allow_nan=False)
    except ValueError as exc:
        raise DatasetError(f"{path}: {exc}; expected finite numbers, nothing written") from None
    if indent is not None:
        text = _NUMBERS.sub(
            lambda m: "[" + ", ".join(m[0][1:-1].replace(",", " ").split()) + "]", text
        )
    write_file(path, lambda tmp: tmp.write_text(text + "\n"))


def machine() -> dict:
    """CPU model, cores, torch version and threads: what the timings depend on."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "torch": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "python": platform.python_version(),
        "platform": platform.platform(),
    }


def claim(out: Path, suite: Suite) -> None:
    """Make ``out`` the suite's output directory, or refuse one that belongs to another suite
    (nothing in it is touched).

    A directory belongs to a suite's name and its data (``[generate]`` or ``datasets``): the
    suite file may change otherwise (models, seeds, budgets, description), as every cell
    carries the rules it was trained by and a cell made under other rules is refused by
    :func:`finished`. ``suite.json`` then records the file's new sha256. The temporaries
    that a run killed while writing a cell or checkpoint left in it are removed (a live run's
    stay: :func:`~simlidar.atomic.clean_stale`).
    """
    marker = out / "suite.json"
    if marker.is_file():
        try:
            owner = json.loads(marker.read_text())
        except (OSError, ValueError):
            owner = {}
        if owner.get("sha256") != suite.sha256:
            if owner.get("name") != suite.name or owner.get("data_sha256") != suite.data_sha256:
                other = "data" if owner.get("name") == suite.name else "suite"
                raise DatasetError(
                    f"--out {out}: belongs to suite {owner.get('name', '?')!r} (data sha256 "
                    f"{str(owner.get('data_sha256'))[:12]}), not to {suite.name!r} (data sha256 "
                    f"{suite.data_sha256[:12]}): another {other}; expected a new --out "
                    "directory (bench replaces nothing), or this one's own suite"
                )
            write_json(marker, _ownership(suite))  # the same suite and data, the file edited
        (out / "cells").mkdir(exist_ok=True)  # removed by hand: its cells are run again
        for folder in ("cells", "checkpoints"):  # what a run killed while writing left there
            clean_stale(out / folder)
        return
    # what a claim that failed midway left: cells/, suite.json's temporaries (a killed
    # write's; .suite.json.partial, a fixed name, from simlidar before write_file)
    litter = {"cells", ".suite.json.partial"}
    if out.exists() and any(
        (p.name not in litter and temporary_of(p.name) != marker.name)
        or (p.name == "cells" and p.is_dir() and any(p.iterdir()))
        for p in out.iterdir()
    ):
        raise DatasetError(
            f"--out {out}: not empty and not a benchmark output directory; "
            "expected a new or empty directory"
        )
    created = not out.exists()
    try:
        (out / "cells").mkdir(parents=True, exist_ok=True)
        clean_stale(out)  # a killed claim's temporary of suite.json (a live one's stays)
        (out / ".suite.json.partial").unlink(missing_ok=True)
        write_json(marker, _ownership(suite))
    except BaseException:  # undo, so that a rerun can claim the folder (write_json left none)
        shutil.rmtree(out if created else out / "cells", ignore_errors=True)
        raise


def _ownership(suite: Suite) -> dict:
    return {
        "name": suite.name,
        "sha256": suite.sha256,
        "data_sha256": suite.data_sha256,
        "path": suite_shown(suite),
    }


def suite_shown(suite: Suite) -> str:
    """The suite file as a reader can find it: ``benchmark/<name>.toml`` for a shipped suite
    (not this machine's install path), the path as given otherwise."""
    shipped = content_dir("benchmark") / suite.path.name
    if shipped.is_file() and shipped.resolve() == suite.path.resolve():
        return f"benchmark/{suite.path.name}"
    return str(suite.path)


# A cell holds a few numbers per test sample (about 23 KB for 600 samples), suite.json a few
# lines: 64 MiB holds the cells of a test split of over a million samples
MAX_JSON_BYTES = 64 * 2**20


def load_json(path: Path, what: str = "a cell as simlidar bench writes it"):
    """A JSON file of a benchmark folder (a cell, ``suite.json``), read as a file from elsewhere:
    a regular file of at most :data:`MAX_JSON_BYTES` (never a named pipe or a device), UTF-8,
    JSON nested no deeper than Python's parser goes, and no NaN (which Python's json module
    reads, and a schema's ranges cannot catch). Anything else is a one-line ResultsError naming
    the file and ``what`` was expected."""

    def constant(name: str) -> float:
        if name == "NaN":
            raise ValueError("NaN is not a number a cell may hold")
        return math.inf if name == "Infinity" else -math.inf

    text = read_text(path, MAX_JSON_BYTES, ResultsError)
    try:
        return json.loads(text, parse_constant=constant)
    except RecursionError:
        raise ResultsError(f"{path}: JSON nested too deeply; expected {what}") from None
    except ValueError as exc:  # not JSON, NaN
        raise ResultsError(f"{path}: cannot be read ({exc}); expected {what}") from None


def read_cell(path: Path) -> dict:
    """A cell's record (:func:`load_json`), the rules of a cell written before null stood for
    no time cap (a bare ``Infinity``) in today's form (:func:`recorded_rules`)."""
    record = load_json(path)
    if not isinstance(record, dict):
        raise ResultsError(f"{path}: a JSON {type(record).__name__}; expected a cell (an object)")
    if isinstance(record.get("budget"), dict):
        record["budget"] = recorded_rules(record["budget"])
    inputs = record.get("inputs")
    if isinstance(inputs, dict) and isinstance(inputs.get("rules"), dict):
        inputs["rules"] = recorded_rules(inputs["rules"])
    return record


def collect(out: Path, suite: Suite) -> dict:
    """results.json from every finished cell in ``out`` (per-sample arrays stay in cells/)."""
    records = []
    for path in sorted((out / "cells").glob("*.json")):
        record = read_cell(path)
        record.pop("per_sample", None)
        records.append(record)
    results = {
        "suite": {"name": suite.name, "sha256": suite.sha256, "description": suite.description},
        "simlidar_version": __version__,  # of the run that wrote this file; cells record theirs
        "machine": machine(),  # that wrote this file; each cell records the one it ran on
        "seconds": round(sum(r["seconds"] for r in records), 1),
        "cells": records,
    }
    write_json(out / "results.json", results)
    return results
