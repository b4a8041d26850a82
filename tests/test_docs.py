"""The examples in the docs run: docs/loading.md (and the other pages' examples) as doctests on
generated datasets."""

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


def test_streams_loading_examples(tmp_path, catalog):
    """docs/streams.md's examples on a small stream dataset (its sample 1 a car: 4 classes)."""
    from simlidar.generator.stream_files import generate_streams

    path = generate_streams(tmp_path, train_size=8, test_size=4, scenes=catalog, progress=False,
                            preview=False)  # fmt: skip
    result = doctest.testfile(
        str(DOCS / "streams.md"),
        module_relative=False,
        globs={"path": str(path)},
        optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
    )
    assert result.attempted >= 15
    assert result.failed == 0


def test_the_benchmark_pages_api_example(datasets, tmp_path):
    result = doctest.testfile(
        str(DOCS / "benchmark.md"),
        module_relative=False,
        globs={"path": str(datasets[0.1]), "out": tmp_path / "mine"},
        optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
    )
    assert result.attempted >= 5
    assert result.failed == 0


def test_the_cli_page_states_the_defaults_the_generate_options_have():
    """docs/cli.md's generate table against the options (made from GeneratorConfig)."""
    import re

    from simlidar.cli import main

    section = (DOCS / "cli.md").read_text().split("## `simlidar generate`")[1].split("\n## ")[0]
    rows = re.findall(r"^\| `(--[a-z-]+)` \| [^|]+ \| ([^|]+) \|", section, re.M)
    options = {opt: p for p in main.commands["generate"].params for opt in p.opts}
    checked = []
    for flag, written in rows:
        option = options[flag]
        if option.default is None or option.is_flag:
            continue  # "the profile's", "the shipped catalog", flags: not a value
        assert written.strip().strip("`") == str(option.default), flag
        checked.append(flag)
    assert {"--classes", "--noise", "--train-size", "--width", "--batch-size"} <= set(checked)


def test_the_cli_page_lists_every_command():
    """Every command of `simlidar` has a row in docs/cli.md's command table (a new command, such
    as `report`, cannot ship undocumented)."""
    import re

    from simlidar.cli import main

    table = (DOCS / "cli.md").read_text().split("| command | what it does |")[1].split("\n\n")[0]
    listed = set(re.findall(r"^\| `([a-z-]+)", table, re.M))
    assert set(main.commands) <= listed, sorted(set(main.commands) - listed)
    assert "report" in main.commands


def test_the_python_api_page_runs(tmp_path):
    """docs/python-api.md's examples: generate, profiles, reuse, simulate, motion, sweeps and
    another sensor from Python."""
    result = doctest.testfile(
        str(DOCS / "python-api.md"),
        module_relative=False,
        globs={"out": tmp_path / "out"},
        optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
    )
    assert result.attempted >= 15
    assert result.failed == 0
