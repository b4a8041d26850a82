"""A non-editable install into a fresh virtual environment can run `simlidar generate`.

The content folders (scenes/, baselines/, benchmark/, profiles/, sensors/) must ship inside
the wheel, and so must the cell schema (simlidar/bench/cell.schema.json). The venv
reuses the running interpreter's installed dependencies (its site-packages, added by a `.pth`
file: this works whether pytest runs in a venv or not, unlike `system_site_packages`, which
reaches the base interpreter), but simlidar itself comes only from the wheel (pip install
--no-index), and the command runs outside the source tree.
"""

import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_wheel_carries_the_catalog_and_generates(tmp_path):
    wheels = tmp_path / "wheels"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(wheels),
            str(ROOT),
        ],
        check=True,
    )
    wheel = next(wheels.glob("simlidar-*.whl"))
    import zipfile

    names = zipfile.ZipFile(wheel).namelist()
    assert "simlidar/_content/scenes/catalog.toml" in names
    assert "simlidar/_content/scenes/layouts/tunnel.toml" in names
    # every recipe, suite, profile and sensor
    for folder in ("baselines", "benchmark", "profiles", "sensors"):
        shipped = {n.split("/")[-1] for n in names if n.startswith(f"simlidar/_content/{folder}/")}
        assert {p.name for p in (ROOT / folder).glob("*.toml")} <= shipped
    # the receivers and materials of issue 41 (the sensor profile reads them)
    for path in [
        *(ROOT / "sensors" / "receivers").glob("*.toml"),
        ROOT / "scenes" / "materials.toml",
    ]:
        assert f"simlidar/_content/{path.relative_to(ROOT).as_posix()}" in names
    assert not [n for n in names if "benchmark/results" in n]
    assert "simlidar/bench/cell.schema.json" in names  # simlidar report checks cells with it
    # the licence pyproject names, as a file of the wheel's metadata
    licence = [n for n in names if n.endswith("LICENSE") and ".dist-info/" in n]
    assert licence and zipfile.ZipFile(wheel).read(licence[0]) == (ROOT / "LICENSE").read_bytes()

    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    python = env_dir / "bin" / "python"
    own_site = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    # Plain paths in a .pth file are appended to sys.path without processing the .pth files
    # found there, so an editable install of simlidar in the running environment stays unseen.
    parents = dict.fromkeys(sysconfig.get_paths()[k] for k in ("purelib", "platlib"))
    (Path(own_site) / "_parent_site.pth").write_text("".join(f"{d}\n" for d in parents))
    subprocess.run(
        [str(python), "-m", "pip", "install", "-q", "--no-deps", "--no-index", str(wheel)],
        check=True,
    )
    work = tmp_path / "elsewhere"
    work.mkdir()
    check = (
        "import simlidar, simlidar.content as c;"
        "assert str(simlidar.__file__).startswith(sys.argv[1]), simlidar.__file__;"
        "assert '_content' in str(c.content_dir('scenes'));"
        "import importlib.resources as r, json;"
        "schema = json.loads(r.files('simlidar.bench').joinpath('cell.schema.json').read_text());"
        "assert 'accuracy' in schema['required']"
    )
    subprocess.run([str(python), "-c", "import sys;" + check, str(env_dir)], cwd=work, check=True)
    done = subprocess.run(
        [str(env_dir / "bin" / "simlidar"), "generate", "--train-size", "32", "--test-size", "32"],
        cwd=work,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    assert (work / "data" / "simlidar-32c-noise0.2-paper-v2.0.0" / "train.h5").is_file()
    listed = subprocess.run(
        [str(env_dir / "bin" / "simlidar"), "sensors"], cwd=work, capture_output=True, text=True
    )
    assert listed.returncode == 0 and "hdl64e: Velodyne HDL-64E S2" in listed.stdout


def test_the_licence_and_the_citation_agree_with_the_package():
    """LICENSE is the MIT licence pyproject declares; CITATION.cff is valid YAML of CFF 1.2.0
    whose version and licence are the package's and which cites the paper the cards cite."""
    import tomllib

    import yaml

    import simlidar
    from simlidar.generator.about import CITATION

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["license"] == "MIT"
    assert (ROOT / "LICENSE").read_text().startswith("MIT License\n")
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["license"] == "MIT"
    assert cff["version"] == simlidar.__version__
    assert cff["authors"] == [{"name": project["authors"][0]["name"]}]
    paper = cff["references"][0]
    assert "arXiv:2001.09220" in paper["journal"] and "arXiv:2001.09220" in CITATION
    assert [a["family-names"] for a in paper["authors"]] == [
        "Wang", "Zhou", "Li", "Li", "Yuan", "Jin"]  # fmt: skip
