"""tests/slow_tests.py names tests that exist: a renamed test would otherwise leave the quick
run (``-m "not slow"``) without a word."""

import ast
from pathlib import Path

from slow_tests import SLOW

ROOT = Path(__file__).resolve().parents[1]


def test_every_slow_test_named_exists():
    missing = []
    for name in sorted(SLOW):
        file, function = name.split("::")
        tree = ast.parse((ROOT / file).read_text())
        if function not in {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)}:
            missing.append(name)
    assert missing == []
    assert len(SLOW) > 50  # the list was measured, not left empty
