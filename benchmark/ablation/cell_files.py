"""The files of cells the ablation scripts write (one JSON object a line) and the tables they
print of them (``--summary``): what ``scnn_variants.py`` and ``cnn_learner_inputs.py`` share."""

import json
from pathlib import Path

import numpy as np


def append_cell(out: Path, row: dict) -> None:
    """Print a finished cell and append it to the file ``out`` (a run stopped midway keeps
    the cells it finished)."""
    line = json.dumps(row)
    print(line, flush=True)
    with out.open("a") as file:
        file.write(line + "\n")


def grouped_cells(path: Path, script: str, fields: str, parse, name) -> dict:
    """{key: [cell, ...]} of a file of cells that ``script`` wrote, read as a file from
    elsewhere (a regular file of at most ``MAX_JSON_BYTES``).

    parse : a line's JSON object -> (key, cell), the cell a dict with its ``seed``; what it
        cannot read (a missing key, a value of another kind) makes the line a one-line
        ResultsError naming the file, the line and ``fields``
    name : key -> its words in the message that refuses a seed a second time in a group (it
        would weigh twice in the mean)
    """
    from simlidar.bench.outdir import MAX_JSON_BYTES
    from simlidar.content import read_text
    from simlidar.errors import ResultsError

    groups: dict = {}
    for number, line in enumerate(read_text(path, MAX_JSON_BYTES, ResultsError).splitlines()):
        try:
            key, cell = parse(json.loads(line))
        except (ValueError, KeyError, TypeError, AttributeError):
            raise ResultsError(
                f"{path}, line {number + 1}: expected a cell of {script} (a JSON object: {fields})"
            ) from None
        if any(c["seed"] == cell["seed"] for c in groups.get(key, [])):
            raise ResultsError(
                f"{path}, line {number + 1}: seed {cell['seed']:.0f} of {name(key)} a second "
                "time; expected each seed once"
            )
        groups.setdefault(key, []).append(cell)
    return groups


def spread(values: np.ndarray) -> str:
    """Mean ± sample standard deviation (0 for one value); a dash where a value is missing."""
    if np.isnan(values).any():
        return "-"
    return f"{values.mean():.2f} ± {values.std(ddof=1) if len(values) > 1 else 0.0:.2f}"
