"""The examples in the docs run: docs/loading.md as doctests on a generated dataset."""

import doctest
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"


def test_loading_examples(datasets):
    result = doctest.testfile(
        str(DOCS / "loading.md"),
        module_relative=False,
        globs={"path": str(datasets[0.1])},
        optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
    )
    assert result.attempted >= 10
    assert result.failed == 0
