"""Benchmark cells read from result folders, each checked against the published cell schema
(``cell.schema.json`` beside this module, JSON Schema draft 2020-12).
"""

import functools
import json
import math
from pathlib import Path

from simlidar.errors import ResultsError

SCHEMA = Path(__file__).with_name("cell.schema.json")
SCHEMA_NAME = "simlidar/bench/cell.schema.json"  # as users find it (the repository, the wheel)


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
    """One cell file, checked against the schema; NaN (which Python's json module reads, and a
    schema's ranges cannot catch) is refused too."""

    def constant(name: str) -> float:
        if name == "NaN":
            raise ValueError("NaN is not a number a cell may hold")
        return math.inf if name == "Infinity" else -math.inf

    try:
        cell = json.loads(path.read_text(), parse_constant=constant)
    except (OSError, ValueError) as exc:  # ValueError: not UTF-8, not JSON, NaN
        raise ResultsError(
            f"{path}: cannot be read ({exc}); expected a cell as simlidar bench writes it"
        ) from None
    check_cell(cell, path)
    return cell
