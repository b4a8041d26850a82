"""The package's stages import one way (docs/architecture.md): a module imports only from its
own stage or the stages below it, including imports made inside functions."""

import ast
from pathlib import Path

import simlidar

PACKAGE = Path(simlidar.__file__).parent
# lowest first; a module may import its own stage and those before it
STAGES = [
    {
        "simlidar",
        "simlidar.errors",
        "simlidar.content",
        "simlidar.atomic",
        "simlidar.resources",
        "simlidar.settings",
        "simlidar.processes",
        "simlidar.cluster",
    },
    {"simlidar.scene"},
    {"simlidar.sensor"},
    {"simlidar.dataset", "simlidar.data"},
    {"simlidar.release"},
    {"simlidar.generator"},
    {"simlidar.convert"},
    {"simlidar.sources"},
    {"simlidar.models"},
    {"simlidar.bench"},
    {"simlidar.cli"},
]


def stage(module: str) -> int:
    """The stage of a dotted module name: its longest prefix listed in STAGES."""
    parts = module.split(".")
    for n in range(len(parts), 0, -1):
        prefix = ".".join(parts[:n])
        for level, names in enumerate(STAGES):
            if prefix in names:
                return level
    raise AssertionError(f"{module}: in no stage of tests/test_architecture.py")


def modules() -> dict[str, Path]:
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found[name] = path
    return found


def imported(path: Path) -> set[str]:
    """Every simlidar module ``path`` imports, at the top or inside a function."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names if a.name.startswith("simlidar")}
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("simlidar"):
            names.add(node.module)
    return names


def test_every_module_imports_only_its_own_stage_or_the_stages_below():
    upward = [
        f"{name} (stage {stage(name)}) imports {other} (stage {stage(other)})"
        for name, path in modules().items()
        for other in sorted(imported(path))
        if stage(other) > stage(name)
    ]
    assert upward == []


def test_the_checker_sees_an_upward_import(tmp_path):
    path = tmp_path / "m.py"
    path.write_text("def f():\n    from simlidar.bench.run import run_suite\n")
    assert stage("simlidar.dataset.reader") < stage(next(iter(imported(path))))
