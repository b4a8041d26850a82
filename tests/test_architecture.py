"""The package's stages import one way (docs/architecture.md): a module imports only from its
own stage or the stages below it, and no modules import each other in a circle, counting
imports made inside functions. No module or script uses another module's private
(underscore) name: a name shared is public. The tests mirror the package: every package folder
has a test folder of its name."""

import ast
import re
from pathlib import Path

import simlidar

PACKAGE = Path(simlidar.__file__).parent
ROOT = PACKAGE.parent
TESTS = Path(__file__).resolve().parent
# The package and the scripts that use it (tests may reach into a module's private parts)
USERS = [PACKAGE, ROOT / "benchmark", ROOT / "examples"]
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
    {"simlidar.motion"},
    {"simlidar.sensor"},
    {"simlidar.dataset", "simlidar.data"},
    {"simlidar.release"},
    {"simlidar.generator"},
    {"simlidar.convert"},
    {"simlidar.any_card"},
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


def imported(path: Path, known=frozenset()) -> set[str]:
    """Every simlidar module ``path`` imports, at the top or inside a function; ``from a
    import b`` counts as ``a.b`` where that is one of the ``known`` modules."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names if a.name.startswith("simlidar")}
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("simlidar"):
            for alias in node.names:
                submodule = f"{node.module}.{alias.name}"
                names.add(submodule if submodule in known else node.module)
    return names


def private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def private_uses(path: Path, known) -> set[str]:
    """The private names of simlidar modules (of ``known``) that ``path`` imports (``from
    simlidar.m import _x``) or reaches through an imported module (``m._x``,
    ``simlidar.m._x``), as dotted names."""
    tree = ast.parse(path.read_text())
    bound = {}  # a local name: the simlidar module it is
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("simlidar"):
            for alias in node.names:
                dotted = f"{node.module}.{alias.name}"
                if private(alias.name):
                    found.add(dotted)
                elif dotted in known:
                    bound[alias.asname or alias.name] = dotted
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("simlidar"):
                    top = alias.name.split(".")[0]
                    bound[alias.asname or top] = alias.name if alias.asname else top

    def module_of(node) -> str | None:
        if isinstance(node, ast.Name):
            return bound.get(node.id)
        if isinstance(node, ast.Attribute):
            base = module_of(node.value)
            return base and f"{base}.{node.attr}"
        return None

    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and private(node.attr):
            base = module_of(node.value)
            if base in known:
                found.add(f"{base}.{node.attr}")
    return found


def cycles(found: dict[str, Path]) -> list[list[str]]:
    """The modules of ``found`` (name: path) that import each other in a circle, one sorted
    list per circle (a strongly connected component of the import graph, Tarjan's
    algorithm)."""
    graph = {
        name: sorted(imported(path, found.keys()) & found.keys()) for name, path in found.items()
    }
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def visit(name: str) -> None:
        index[name] = low[name] = len(index)
        stack.append(name)
        for other in graph[name]:
            if other not in index:
                visit(other)
                low[name] = min(low[name], low[other])
            elif other in stack:
                low[name] = min(low[name], index[other])
        if low[name] == index[name]:
            members = []
            while not members or members[-1] != name:
                members.append(stack.pop())
            if len(members) > 1 or name in graph[name]:
                circles.append(sorted(members))

    for name in sorted(graph):
        if name not in index:
            visit(name)
    return sorted(circles)


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


def test_no_modules_import_each_other_in_a_circle():
    assert cycles(modules()) == []


def test_the_checker_sees_a_circle(tmp_path):
    (tmp_path / "a.py").write_text("from simlidar.pkg import b\n")
    (tmp_path / "b.py").write_text("def f():\n    import simlidar.pkg.a\n")
    (tmp_path / "c.py").write_text("from simlidar.pkg.a import x\n")  # into the circle, not in it
    found = {f"simlidar.pkg.{n}": tmp_path / f"{n}.py" for n in "abc"}
    assert cycles(found) == [["simlidar.pkg.a", "simlidar.pkg.b"]]


def test_no_module_uses_another_modules_private_names():
    known = modules().keys()
    used = {
        (str(path.relative_to(ROOT)), name)
        for folder in USERS
        for path in sorted(folder.rglob("*.py"))
        for name in private_uses(path, known)
    }
    assert sorted(used) == []


def test_the_checker_sees_a_private_name(tmp_path):
    path = tmp_path / "m.py"
    path.write_text(
        "import simlidar.dataset.reader\n"
        "from simlidar.generator import simulate as sim\n"
        "from simlidar.errors import __doc__, first_line\n"
        "def f():\n"
        "    from simlidar.bench.tables import _num\n"
        "    return sim._x, simlidar.dataset.reader._decode, sim.simulate, first_line._y\n"
    )
    assert private_uses(path, modules().keys()) == {
        "simlidar.bench.tables._num",
        "simlidar.generator.simulate._x",
        "simlidar.dataset.reader._decode",
    }


def untested_folders(package: Path, tests: Path) -> list[str]:
    """The package folders of ``package`` (those with an ``__init__.py``, at any depth) that
    have no folder of the same path under ``tests`` holding a ``test_*.py`` file."""
    return [
        str(init.parent.relative_to(package))
        for init in sorted(package.rglob("__init__.py"))
        if init.parent != package
        and "__pycache__" not in init.parts
        and not any((tests / init.parent.relative_to(package)).glob("test_*.py"))
    ]


def test_every_package_folder_has_its_test_folder():
    missing = untested_folders(PACKAGE, TESTS)
    assert not missing, "; ".join(f"simlidar/{m}/ has no tests/{m}/test_*.py" for m in missing)


def test_the_checker_sees_a_folder_without_tests(tmp_path):
    for folder in ("package/a", "package/b", "package/b/c", "package/d/__pycache__"):
        (tmp_path / folder).mkdir(parents=True)
        (tmp_path / folder / "__init__.py").touch()
    (tmp_path / "package" / "__init__.py").touch()
    (tmp_path / "tests" / "a").mkdir(parents=True)
    (tmp_path / "tests" / "a" / "test_x.py").touch()
    (tmp_path / "tests" / "b").mkdir()
    (tmp_path / "tests" / "b" / "conftest.py").touch()  # a folder, but no tests in it
    assert untested_folders(tmp_path / "package", tmp_path / "tests") == ["b", "b/c"]


# Public functions of five parameters or more whose docstrings do not yet name every parameter
# (issue 44, item 5: the convention in docs/architecture.md, "Docstrings"). The debt, which
# could only shrink, is paid: the set is empty, and a function that does not name them all
# fails the test.
UNDOCUMENTED: set[str] = set()


def parameters_unnamed(path: Path) -> dict[str, list[str]]:
    """Per public function of five parameters or more in ``path`` (methods too; ``self`` and
    ``cls`` aside): the parameters its docstring does not name."""
    found = {}
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            names = [a.arg for a in node.args.args + node.args.kwonlyargs]
            names = [n for n in names if n not in ("self", "cls")]
            doc = ast.get_docstring(node) or ""
            if len(names) >= 5:
                found[node.name] = [n for n in names if not re.search(rf"\b{n}\b", doc)]
    return found


def test_public_functions_of_five_parameters_or_more_name_each_in_their_docstring():
    """The command line's functions are click commands, whose options say what they are."""
    unnamed, named = {}, set()
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.relative_to(PACKAGE).parts[0] == "cli":
            continue
        for function, missing in parameters_unnamed(path).items():
            key = f"{path.relative_to(PACKAGE.parent).as_posix()}:{function}"
            if missing and key not in UNDOCUMENTED:
                unnamed[key] = missing
            elif not missing and key in UNDOCUMENTED:
                named.add(key)
    assert not unnamed, f"parameters their docstrings do not name: {unnamed}"
    assert not named, f"documented now: take them out of UNDOCUMENTED: {sorted(named)}"
