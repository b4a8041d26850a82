"""The finished cells of several benchmark runs in one report (``simlidar report``).

Each run is a folder that ``simlidar bench`` wrote (``cells/*.json``; a ``suite.json`` names its
suite). Every cell is checked against the published cell schema (``cell.schema.json`` beside
this module, JSON Schema draft 2020-12), and the cells of different folders must agree on
their data: cells of one dataset name made from different split files (``inputs.splits_sha256``)
are refused, and so are two different cells of the same (dataset, model, seed); identical
copies are kept once. All of that is checked before anything is written; the report is then
built in a hidden temporary folder and moved to ``--out`` in one step (:mod:`simlidar.atomic`).

The report groups cells by model name, and the accuracy-by-noise table and figure group a
model's cells by noise level alone. So a model whose cells from different folders were made
from another recipe of the same name, under other training rules, or on different datasets
at the same noise level (a user's 8-class dataset and the paper's 32-class one at noise 0.1,
say) is shown once per folder, ``cnn (paper)`` and ``cnn (mine)``, instead of being averaged
into one row.
"""

import functools
import json
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

from simlidar import __version__
from simlidar.atomic import building
from simlidar.bench.outdir import load_json, machine, write_json
from simlidar.bench.report import write_report
from simlidar.errors import ResultsError

SCHEMA = Path(__file__).with_name("cell.schema.json")
SCHEMA_NAME = "simlidar/bench/cell.schema.json"  # as users find it (the repository, the wheel)
# what write_report and this module write into --out: an earlier report may be replaced
REPORT_FILES = {
    "results.json",
    "report.md",
    "accuracy_vs_noise.png",
    "decisions.png",
    "confusion.png",
}


@functools.cache
def _validator():
    from jsonschema import Draft202012Validator

    return Draft202012Validator(json.loads(SCHEMA.read_text()))


def check_cell(cell, where: str | Path) -> None:
    """Refuse a cell that does not follow :data:`SCHEMA`: a ResultsError naming ``where``, the
    key and what was expected (the most relevant of its problems, on one line)."""
    from jsonschema.exceptions import best_match

    error = best_match(_validator().iter_errors(cell))
    if error is None:
        return
    key = ".".join(map(str, error.absolute_path))
    message = " ".join(error.message.split())
    if len(message) > 160:  # a message may quote a whole value (a confusion matrix)
        message = message[:157] + "..."
    raise ResultsError(
        f"{where}: {f'key {key!r}' if key else 'the cell'}: {message}; expected a cell as "
        f"{SCHEMA_NAME} describes"
    )


def read_cell(path: Path) -> dict:
    """One cell file (:func:`~simlidar.bench.outdir.load_json`), checked against the schema."""
    cell = load_json(path)
    check_cell(cell, path)
    return cell


@dataclass
class Run:
    """One benchmark output folder: its cells (path -> cell) and the name it is shown by."""

    folder: Path
    suite: str | None  # the suite's name from suite.json, if there is one
    cells: dict[Path, dict] = field(default_factory=dict)
    label: str = ""


def read_run(folder: Path) -> Run:
    """The finished cells of a benchmark output folder, each checked (:func:`read_cell`)."""
    if not folder.is_dir():
        raise ResultsError(
            f"{folder}: not a folder; expected a benchmark output folder (cells/*.json, as "
            "simlidar bench writes)"
        )
    paths = sorted((folder / "cells").glob("*.json"))
    if not paths:
        raise ResultsError(
            f"{folder}: no finished cells (cells/*.json); expected a benchmark output folder "
            "written by simlidar bench"
        )
    suite = None
    try:  # never opens a pipe or a device in its place (load_json)
        owner = load_json(folder / "suite.json", "suite.json as simlidar bench writes it")
        suite = owner.get("name") if isinstance(owner, dict) else None
    except ResultsError:
        pass  # cells without suite.json (written by the Python API, copied by hand) are fine
    run = Run(folder, suite if isinstance(suite, str) and suite else None)
    for path in paths:
        run.cells[path] = read_cell(path)
    return run


def _label(runs: list[Run]) -> None:
    """Each run's label: its suite's name; where two runs share one, the folder's name, or the
    folder as given where that is shared too."""
    names = [run.suite or run.folder.name for run in runs]
    folders = [run.folder.name for run in runs]
    for run, name in zip(runs, names):
        if names.count(name) == 1:
            run.label = name
        elif folders.count(run.folder.name) == 1 and run.folder.name not in names:
            run.label = run.folder.name
        else:
            run.label = str(run.folder)


def check_data(runs: list[Run]) -> None:
    """Cells of one dataset name come from the same split files (``inputs.splits_sha256``); a
    cell without a digest (a dataset without SHA256SUMS) cannot be shown to, and is refused as
    soon as another folder has a cell of that dataset."""
    digests = defaultdict(dict)  # dataset -> {digest: a cell's path}
    folders = defaultdict(dict)  # dataset -> {folder: a cell's path}
    for run in runs:
        for path, cell in run.cells.items():
            digests[cell["dataset"]].setdefault(cell["inputs"]["splits_sha256"], path)
            folders[cell["dataset"]].setdefault(run.folder, path)
    for dataset, found in digests.items():
        known = [(digest, path) for digest, path in found.items() if digest is not None]
        if len(known) > 1:
            (a, path_a), (b, path_b) = known[:2]
            raise ResultsError(
                f"dataset {dataset}: {path_a} and {path_b} were made from different data of "
                f"that name (splits_sha256 {a[:12]}, {b[:12]}); expected one dataset per name: "
                "run the models on the same data (simlidar bench --suite paper --models ... "
                "makes the paper suite's datasets byte for byte)"
            )
        blind = found.get(None)
        others = [p for folder, p in folders[dataset].items() if blind and folder != _run_of(blind)]
        if others:
            raise ResultsError(
                f"dataset {dataset}: {blind} records no data digest (inputs.splits_sha256 null: "
                f"its dataset had no SHA256SUMS), so it cannot be shown to hold the data of "
                f"{others[0]}; expected cells whose digests can be compared"
            )


def _run_of(cell: Path) -> Path:
    """The folder of a cell file (``<folder>/cells/<id>.json``), as it was given."""
    return cell.parent.parent


def merge_cells(runs: list[Run]) -> list[dict]:
    """The cells of every run, each once: two cells of the same (dataset, model, seed) must be
    identical (one copy kept), or a ResultsError names both. Each merged cell records its
    folder as ``origin``."""
    kept = {}  # (dataset, model, seed) -> (path, cell)
    for run in runs:
        for path, cell in run.cells.items():
            key = (cell["dataset"], cell["model"], cell["seed"])
            if key not in kept:
                kept[key] = (path, {**cell, "origin": str(run.folder)})
                continue
            first, earlier = kept[key]
            differ = sorted(
                k for k in {*cell, *earlier} - {"origin"} if cell.get(k) != earlier.get(k)
            )
            if differ:  # named by the cause (another recipe) before its results (accuracy)
                why = _conflict([earlier, cell]) or f"key {differ[0]!r}"
                raise ResultsError(
                    f"cell ({key[0]}, {key[1]}, seed {key[2]}) is in {first} and in {path}, "
                    f"which differ ({why}); expected one cell per dataset, model and seed, or "
                    "identical copies"
                )
    return [cell for _, cell in kept.values()]


def _conflict(cells: list[dict]) -> str | None:
    """What a model's cells from several folders differ in, so that they cannot share one row
    (recipe, training rules, datasets at one noise level), or None."""
    differ = []
    if len({c["inputs"]["recipe_sha256"] for c in cells}) > 1:
        differ.append("recipe")
    if len({json.dumps(c["inputs"]["rules"], sort_keys=True) for c in cells}) > 1:
        differ.append("training rules")
    datasets = defaultdict(set)
    for c in cells:
        datasets[c["source"], c["noise"]].add(c["dataset"])
    for (_, noise), names in sorted(datasets.items()):
        if len(names) > 1:
            differ.append(f"datasets at noise {noise:g} ({', '.join(sorted(names))})")
            break
    return " and ".join(differ) or None


def separate(cells: list[dict], runs: list[Run]) -> list[str]:
    """Show a model once per folder (``cnn (paper)``) where its folders' cells would otherwise
    be averaged across different recipes, rules or data (:func:`_conflict`); the cells'
    ``model`` is renamed in place. Returns one sentence per reason, naming the models."""
    labels = {str(run.folder): run.label for run in runs}
    by_model = defaultdict(list)
    for cell in cells:
        by_model[cell["model"]].append(cell)
    renamed = defaultdict(list)  # (why, labels) -> models
    for model, group in sorted(by_model.items()):
        origins = sorted({c["origin"] for c in group}, key=list(labels).index)
        why = _conflict(group) if len(origins) > 1 else None
        if why is None:
            continue
        for cell in group:
            cell["model"] = f"{model} ({labels[cell['origin']]})"
        renamed[why, tuple(labels[o] for o in origins)].append(model)
    return [
        f"{', '.join(models)} {'is' if len(models) == 1 else 'are'} shown once per run "
        f"({', '.join(shown)}): {'its' if len(models) == 1 else 'their'} cells differ in {why}."
        for (why, shown), models in renamed.items()
    ]


def check_out(out: Path) -> None:
    """``out`` may be new, empty, or a report this module wrote before (replaced); anything
    else is refused before anything is written."""
    if not out.exists() and not out.is_symlink():
        return
    if not out.is_dir():
        raise ResultsError(f"--out {out}: not a folder; expected a new folder for the report")
    entries = {p.name for p in out.iterdir()}
    earlier = False
    if entries and entries <= REPORT_FILES and "results.json" in entries:
        try:
            earlier = "merged_from" in load_json(out / "results.json", "a report's results")
        except (ResultsError, TypeError):
            earlier = False
    if entries and not earlier:
        raise ResultsError(
            f"--out {out}: not empty and not a folder written by simlidar report; expected a "
            "new or empty folder, or an earlier report to replace"
        )


def _runs(count: int) -> str:
    return f"{count} benchmark run{'' if count == 1 else 's'}"


def merge_report(folders: list[Path], out: Path) -> tuple[dict, list[str]]:
    """Merge the cells of ``folders`` into ``out``: results.json (the cells without their
    per-sample arrays, ``merged_from`` naming the folders), report.md and its pictures.

    returns : the results, and one sentence per model shown once per folder (:func:`separate`)
    """
    unique = list({folder.resolve(): folder for folder in folders}.values())  # given twice: once
    runs = [read_run(folder) for folder in unique]
    _label(runs)
    check_data(runs)
    cells = merge_cells(runs)
    check_out(out)
    notes = separate(cells, runs)
    counted = defaultdict(int)
    for cell in cells:
        counted[cell["origin"]] += 1
    sources = [
        {"folder": str(run.folder), "suite": run.suite, "cells": counted[str(run.folder)]}
        for run in runs
    ]
    shown = ", ".join(
        f"`{s['folder']}` ("
        + (f"suite {s['suite']}, " if s["suite"] else "")
        + f"{s['cells']} cells)"
        for s in sources
    )
    results = {
        "suite": {
            "name": " + ".join(run.label for run in runs),
            "description": " ".join(
                [f"The cells of {_runs(len(runs))}, merged by `simlidar report`: {shown}."] + notes
            ),
        },
        "merged_from": sources,
        "simlidar_version": __version__,  # of the run that wrote this file; cells record theirs
        "machine": machine(),  # that wrote this file; each cell records the one it ran on
        "seconds": round(sum(c["seconds"] for c in cells), 1),
        "cells": [{k: v for k, v in c.items() if k != "per_sample"} for c in cells],
    }
    final = out.resolve()
    with building(final.parent, final.name, force=True) as temporary:
        write_json(temporary / "results.json", results)
        write_report(results, temporary, sampled=cells)
    return results, notes
